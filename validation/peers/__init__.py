"""Peers: other renderers on the same scenes (validation/README.md)."""
