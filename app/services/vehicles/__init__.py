"""Vehicles: their parameter versions and reprocessing (``versions``), calibration from
stored runs, and a run's declared load."""
