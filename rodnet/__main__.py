"""``python -m rodnet`` is the ``rodnet`` command."""

from rodnet.cli import main

raise SystemExit(main())
