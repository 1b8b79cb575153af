"""pilotlab: make end-to-end driving networks fast without making them drive worse."""
__version__ = "0.1.0"
