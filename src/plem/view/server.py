"""The view's web server: viser, serving its own built client (no internet needed) on a local port."""

from __future__ import annotations

import contextlib
import io
import ipaddress
import logging
import socket
import time

import viser

from plem.errors import PlemError

DEFAULT_HOST, DEFAULT_PORT = "127.0.0.1", 8080
#: The light from above and below that replaces viser's image-based lighting (docs/decisions.md: filtering its
#: environment image freezes a browser that draws WebGL on the CPU for 7 s to half a minute before the first frame).
SKY_RGB, GROUND_RGB, HEMISPHERE_INTENSITY = (255, 255, 255), (110, 110, 120), 3.0
#: The logger through which the websocket server reports a client's message that viser could not handle.
WEBSOCKET_LOGGER = "websockets.server"
#: Seconds between the lines that count malformed frames.
MALFORMED_REPORT_PERIOD_S = 10.0


class ViewError(PlemError):
    """The view cannot start or cannot show what was asked."""


def loopback(host: str) -> bool:
    """Whether only this host can reach a server bound to `host`."""
    try:
        return ipaddress.ip_address(socket.gethostbyname(host)).is_loopback
    except (OSError, ValueError):
        return False


class MalformedFrames(logging.Filter):
    """Keeps the tracebacks of clients' malformed websocket frames out of the terminal: each becomes a count, and at
    most one line per MALFORMED_REPORT_PERIOD_S says how many frames from how many clients were ignored so far.

    A page that is not viser's own client (or a hostile one) must not fill the user's terminal; viser closes its
    connection and serves every other client on.
    """

    def __init__(self) -> None:
        super().__init__()
        self.frames = 0
        self.clients: set[object] = set()
        self.kinds: set[str] = set()
        self._next_report = 0.0

    def filter(self, record: logging.LogRecord) -> bool:
        """Count a failed connection handler; let through only the periodic line that counts them."""
        if record.exc_info is None or record.getMessage() != "connection handler failed":
            return True
        connection = getattr(record, "websocket", None)
        self.frames += 1
        self.clients.add(getattr(connection, "id", None) or id(record))
        self.kinds.add(type(record.exc_info[1]).__name__)
        now = time.monotonic()
        if now < self._next_report:
            return False
        self._next_report = now + MALFORMED_REPORT_PERIOD_S
        record.msg, record.args, record.exc_info, record.exc_text = self.summary(), (), None, None
        record.levelno, record.levelname = logging.WARNING, "WARNING"
        return True

    def summary(self) -> str:
        """One line: malformed frames ignored, from how many clients, and what was wrong with them."""
        return (f"plem view: malformed frames from {len(self.clients)} clients ignored ({self.frames} in all: "
                f"{', '.join(sorted(self.kinds))}); the view serves on")


#: The one filter of this process (servers started in one process share the websocket logger).
malformed_frames = MalformedFrames()


def start_server(host: str, port: int, title: str) -> viser.ViserServer:
    """A viser server on `host`, at `port` or the next free one; the share button (a public tunnel) is hidden,
    the scene is lit by plain lights, which every browser draws at once, and malformed frames are only counted."""
    try:
        socket.getaddrinfo(host, port)
    except OSError as error:
        raise ViewError(f"cannot serve the view on {host}", what="a host name or address of this machine",
                        why=str(error), how="pass --host 127.0.0.1 (this machine only) or an address of it") from None
    logging.getLogger(WEBSOCKET_LOGGER).addFilter(malformed_frames)   # adding it again changes nothing
    with contextlib.redirect_stdout(io.StringIO()):  # viser prints a banner; plem prints the URL itself
        server = viser.ViserServer(host=host, port=port, label=title, verbose=False)
    server.gui.configure_theme(show_share_button=False, control_width="large")
    server.scene.configure_environment_map(hdri=None)
    server.scene.add_light_hemisphere("/light", sky_color=SKY_RGB, ground_color=GROUND_RGB,
                                      intensity=HEMISPHERE_INTENSITY)
    return server


def url(server: viser.ViserServer) -> str:
    """The address to open in a browser."""
    host = server.get_host()
    return f"http://{'localhost' if host in ('0.0.0.0', '::') else host}:{server.get_port()}"
