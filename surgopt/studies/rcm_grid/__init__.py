"""The rcm_grid study: its declaration (study.py), config, figures and report page."""
