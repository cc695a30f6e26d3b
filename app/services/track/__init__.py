"""A track's knowledge built from its runs: alignment and the aggregated profile, the
two-load separation kept up to date (``separation_store``) and its history, the soft-spot
register, EN 13848 quality, surveys, centerlines, and deleting a track."""
