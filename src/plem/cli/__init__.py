"""The `plem` command line."""

from plem.cli.app import app, main, run

__all__ = ["app", "main", "run"]
