"""API tests: the service through HTTP against a real SQLite file."""
