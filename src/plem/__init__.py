"""plem: bring up, configure and run 6- and 7-axis robot arms in real time."""

__version__ = "0.1.0"

__all__ = ["__version__"]
