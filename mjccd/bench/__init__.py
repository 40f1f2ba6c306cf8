"""Benchmarks: mjccd against peer libraries and published figures."""
