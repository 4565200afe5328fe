"""The test suite. A package so that ``tests.oracles`` imports from the repository root (pytest, benchmarks)."""
