"""plem: bring up, configure and run 6- and 7-axis robot arms in real time."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("plem")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0"

__all__ = ["__version__"]
