"""Benchmarks of powerline_control against its peers; ``python -m benchmarks`` runs them all."""
