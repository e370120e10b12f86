"""Core services shared by every part of plem: configuration, package paths, files."""
