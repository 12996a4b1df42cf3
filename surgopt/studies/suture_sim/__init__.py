"""The suture_sim study: its declaration (study.py), config, figures and report page."""
