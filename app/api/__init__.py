"""HTTP API: routers by resource under ``app.api.routes``."""
