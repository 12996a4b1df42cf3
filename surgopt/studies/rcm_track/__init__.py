"""The rcm_track study: its declaration (study.py), config, figures and report page."""
