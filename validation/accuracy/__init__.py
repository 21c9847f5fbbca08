"""Accuracy: the engine against independent references (validation/README.md)."""
