"""The bridge's wait for the emulated autopilot's scenario: it outlasts an emulator that is still warming
up, and ends at once when the emulator goes away."""

from __future__ import annotations

import json
import threading
import time

import pytest

from alight.errors import ConfigError
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
        with pytest.raises(ConfigError, match="give --scenario"):
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
        with pytest.raises(ConfigError, match="give --scenario"):
            bridge_run._scenario(cam, None)
        assert time.monotonic() - t0 < 10.0
    finally:
        thread.join(5.0)
        cam.close()
        server.close()
