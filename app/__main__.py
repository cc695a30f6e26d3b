"""``python -m app``: management commands (see :mod:`app.cli`)."""

from app.cli import main

raise SystemExit(main())
