"""Application services: reading uploads, processing and storing runs, the background worker."""
