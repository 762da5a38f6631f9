"""``python -m rkmpc.cli``."""

from rkmpc.cli import main

raise SystemExit(main())
