"""``python -m companion``: same as the ``companion`` console script."""

from companion.commands.main import main

raise SystemExit(main())
