"""The view's web server: viser, serving its own built client (no internet needed) on a local port."""

from __future__ import annotations

import contextlib
import io
import ipaddress
import socket

import viser

from plem.errors import PlemError

DEFAULT_HOST, DEFAULT_PORT = "127.0.0.1", 8080
#: The light from above and below that replaces viser's image-based lighting (docs/decisions.md: filtering its
#: environment image freezes a browser that draws WebGL on the CPU for 7 s to half a minute before the first frame).
SKY_RGB, GROUND_RGB, HEMISPHERE_INTENSITY = (255, 255, 255), (110, 110, 120), 3.0


class ViewError(PlemError):
    """The view cannot start or cannot show what was asked."""


def loopback(host: str) -> bool:
    """Whether only this host can reach a server bound to `host`."""
    try:
        return ipaddress.ip_address(socket.gethostbyname(host)).is_loopback
    except (OSError, ValueError):
        return False


def start_server(host: str, port: int, title: str) -> viser.ViserServer:
    """A viser server on `host`, at `port` or the next free one; the share button (a public tunnel) is hidden and
    the scene is lit by plain lights, which every browser draws at once."""
    try:
        socket.getaddrinfo(host, port)
    except OSError as error:
        raise ViewError(f"cannot serve the view on {host}", what="a host name or address of this machine",
                        why=str(error), how="pass --host 127.0.0.1 (this machine only) or an address of it") from None
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
