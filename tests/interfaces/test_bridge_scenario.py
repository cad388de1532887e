"""The bridge's wait for the emulated autopilot's scenario: it outlasts an emulator that is still warming
up, and ends at once when the emulator goes away."""

from __future__ import annotations

import json
import socket
import threading
import time

import pytest

from alight.errors import InputError
from alight.interfaces import bridge_run
from alight.interfaces.camera_source import KIND_SCENARIO, FrameServer, SocketCameraSource, encode_message
from alight.scenario import Scenario


def _serve_after(server: FrameServer, delay_s: float, hello: bytes | None) -> threading.Thread:
    """Accept the client only after ``delay_s`` (an emulator busy warming up), then send ``hello`` or, with
    None, close the stream without a scenario (an emulator that ended)."""

    def run() -> None:
        time.sleep(delay_s)
        server.hello = hello
        while not server.connected:
            time.sleep(0.01)
        if hello is None:
            assert server._client is not None
            server._client.close()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def test_the_scenario_of_an_emulator_slower_than_the_old_10_s_is_waited_for(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    # The wait is scaled down (the real one is minutes); what is checked is that it, not a fixed 10 s,
    # bounds the wait: with a 1.5 s budget, a scenario sent after 0.8 s arrives.
    monkeypatch.setattr(bridge_run, "EMULATOR_SCENARIO_WAIT_S", 1.5)
    scenario = Scenario.model_validate({"preset": "falanga2017", "seed": 5})
    server = FrameServer()
    hello = encode_message(KIND_SCENARIO, json.dumps(scenario.model_dump(mode="json")).encode())
    thread = _serve_after(server, 0.8, hello)
    cam = SocketCameraSource("127.0.0.1", server.port)
    try:
        got = bridge_run._scenario(cam, None)
    finally:
        thread.join(5.0)
        cam.close()
        server.close()
    assert got == scenario
    monkeypatch.setattr(bridge_run, "EMULATOR_SCENARIO_WAIT_S", 0.3)
    server2 = FrameServer()
    thread2 = _serve_after(server2, 0.8, hello)
    cam2 = SocketCameraSource("127.0.0.1", server2.port)
    try:
        with pytest.raises(InputError, match="sent no scenario within 0.3 s"):
            bridge_run._scenario(cam2, None)
    finally:
        thread2.join(5.0)
        cam2.close()
        server2.close()


def test_an_emulator_that_closes_without_a_scenario_ends_the_wait_at_once() -> None:
    assert bridge_run.EMULATOR_SCENARIO_WAIT_S >= 60.0  # an emulator's warm-up, not a network round trip
    server = FrameServer()
    thread = _serve_after(server, 0.2, None)
    cam = SocketCameraSource("127.0.0.1", server.port)
    t0 = time.monotonic()
    try:
        with pytest.raises(InputError, match="closed its camera stream before sending its scenario"):
            bridge_run._scenario(cam, None)
        assert time.monotonic() - t0 < 10.0
    finally:
        thread.join(5.0)
        cam.close()
        server.close()


def test_a_socket_connected_to_itself_is_not_taken_for_the_emulator(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    # Retrying a loopback port in the ephemeral range before anything listens there can connect the
    # socket to itself (TCP simultaneous open; about 1 in 70 sequences of 200 retries on Linux). Such a
    # socket held the emulator's port and the bridge then waited for a scenario that never came. Here the
    # first attempt is made to connect to itself; the source must drop it and reach the real server.
    server = FrameServer()
    real = socket.create_connection
    calls = []

    def first_to_itself(address, timeout=None):  # type: ignore[no-untyped-def]
        calls.append(address)
        if len(calls) == 1:
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.bind(("127.0.0.1", 0))
            s.connect(s.getsockname())
            assert s.getsockname() == s.getpeername()
            return s
        return real(address, timeout=timeout)

    monkeypatch.setattr(socket, "create_connection", first_to_itself)
    cam = SocketCameraSource("127.0.0.1", server.port)
    try:
        assert len(calls) == 2 and cam.open
        assert cam._sock is not None and cam._sock.getpeername()[1] == server.port
    finally:
        cam.close()
        server.close()
