"""Database layer: ORM models, engine and sessions, migrations."""
