"""Synthetic networks with known truth (tests, example projects, design)."""
