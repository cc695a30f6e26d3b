"""TrackProfile web service: upload run logs, store loaded profiles per chainage, serve them."""

__version__ = "0.1.0"
