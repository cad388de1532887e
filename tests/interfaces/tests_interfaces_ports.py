"""Free loopback ports for the emulated autopilot's tests.

They are picked below Linux's ephemeral range (32768-60999 by default), from which the kernel draws the
source port of every outgoing connection: a test port there can be taken by another connection between
the check and the bind, and a client retrying a loopback port there can be connected to itself (TCP
simultaneous open; it happened to CI on 2026-11-28). Ports handed out once are not handed out again in
the same process: two emulators started one after the other get different pairs."""

from __future__ import annotations

import random
import socket

LOW, HIGH = 20000, 32000
_given: set[int] = set()
_pick = random.Random()  # not a result's randomness: any free port will do


def _free(kind: int, port: int) -> bool:
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def free_port_pair() -> int:
    """A UDP port whose TCP neighbour (the camera stream) is free too."""
    for _ in range(200):
        port = _pick.randrange(LOW, HIGH, 2)
        if port in _given or port + 1 in _given:
            continue
        if _free(socket.SOCK_DGRAM, port) and _free(socket.SOCK_STREAM, port + 1):
            _given.update((port, port + 1))
            return port
    raise RuntimeError(f"no free port pair in {LOW}-{HIGH}")
