"""Performance: what speed costs, and benchmarks (validation/README.md)."""
