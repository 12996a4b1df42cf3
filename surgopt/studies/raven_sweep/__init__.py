"""The raven_sweep study: its declaration (study.py), config, figures and report page."""
