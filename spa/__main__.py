"""``python -m spa``: the same as the ``spa`` command."""

from spa.cli import main

raise SystemExit(main())
