"""Configuration, errors, security and middleware of the web service."""
