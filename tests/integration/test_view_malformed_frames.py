"""plem view's websocket: malformed frames from clients never print tracebacks; they are counted in one line."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import urllib.request

import msgspec.msgpack
import viser
from websockets.asyncio.client import connect

from plem.view.server import WEBSOCKET_LOGGER, malformed_frames, start_server

#: What a client that is not viser's page may send: not MessagePack, a text frame, an unknown message type, a
#: message of the wrong shape, one without its fields.
FRAMES: list[bytes | str] = [
    b"\x00\x01garbage", "a text frame", msgspec.msgpack.encode({"type": "NoSuchMessage"}),
    msgspec.msgpack.encode({"type": "GuiUpdateMessage", "id": "x", "updates": 5}),
    msgspec.msgpack.encode({"type": "ViewerCameraMessage"}),
]


async def send_each(port: int) -> None:
    """Each frame from a client of its own, which then waits for the server to close the connection."""
    for data in FRAMES:
        async with connect(f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"]) as websocket:
            await websocket.send(data)
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(websocket.wait_closed(), 10)


def test_malformed_frames_are_counted_without_tracebacks(caplog, capfd):
    server = start_server("127.0.0.1", 8090, "malformed frames")
    try:
        frames, clients = malformed_frames.frames, len(malformed_frames.clients)
        with caplog.at_level(logging.WARNING):
            asyncio.run(send_each(server.get_port()))
        assert malformed_frames.frames - frames == len(FRAMES)
        assert len(malformed_frames.clients) - clients == len(FRAMES)
        assert {"DecodeError", "AssertionError", "KeyError", "TypeError"} <= malformed_frames.kinds
        websocket_records = [record for record in caplog.records if record.name == WEBSOCKET_LOGGER]
        assert all(record.exc_info is None and "malformed frames from" in record.getMessage()
                   for record in websocket_records), [record.getMessage() for record in websocket_records]
        assert not any(record.exc_info for record in caplog.records)
        assert len(websocket_records) <= 1
        assert "Traceback" not in capfd.readouterr().err
        with urllib.request.urlopen(f"http://127.0.0.1:{server.get_port()}/", timeout=10) as page:   # serves on
            assert page.status == 200
    finally:
        server.stop()


def test_the_count_is_one_line():
    line = malformed_frames.summary()
    assert "\n" not in line and line.startswith("plem view: malformed frames from")
