"""The view's web server: viser, serving its own built client (no internet needed) on a local port."""

from __future__ import annotations

import contextlib
import io
import ipaddress
import socket

import viser

from plem.errors import PlemError

DEFAULT_HOST, DEFAULT_PORT = "127.0.0.1", 8080


class ViewError(PlemError):
    """The view cannot start or cannot show what was asked."""


def loopback(host: str) -> bool:
    """Whether only this host can reach a server bound to `host`."""
    try:
        return ipaddress.ip_address(socket.gethostbyname(host)).is_loopback
    except (OSError, ValueError):
        return False


def start_server(host: str, port: int, title: str) -> viser.ViserServer:
    """A viser server on `host`, at `port` or the next free one; the share button (a public tunnel) is hidden."""
    try:
        socket.getaddrinfo(host, port)
    except OSError as error:
        raise ViewError(f"cannot serve the view on {host}", what="a host name or address of this machine",
                        why=str(error), how="pass --host 127.0.0.1 (this machine only) or an address of it") from None
    with contextlib.redirect_stdout(io.StringIO()):  # viser prints a banner; plem prints the URL itself
        server = viser.ViserServer(host=host, port=port, label=title, verbose=False)
    server.gui.configure_theme(show_share_button=False, control_width="large")
    return server


def url(server: viser.ViserServer) -> str:
    """The address to open in a browser."""
    host = server.get_host()
    return f"http://{'localhost' if host in ('0.0.0.0', '::') else host}:{server.get_port()}"
