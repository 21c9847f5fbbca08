"""Tools: checks for refactors (validation/README.md)."""
