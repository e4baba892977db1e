"""``python -m station`` is the ``station`` command."""

from station.cli.main import main

raise SystemExit(main())
