"""The port_place study: its declaration (study.py), config, figures and report page."""
