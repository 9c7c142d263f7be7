"""``python -m sitl_model``: same as the ``sitl-model`` console script."""

from sitl_model.cli import main

raise SystemExit(main())
