"""``python -m companion``: same as the ``companion`` console script."""

from companion.cli import main

raise SystemExit(main())
