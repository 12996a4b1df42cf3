"""Embedded default configs (the papers' own setups)."""
