"""The command line: :mod:`~companion.commands.main` is ``companion`` (one sub-command per
module here, each ``register(subparsers)`` and ``run(args)``: argparse and calls, nothing
else). The package imports none of them."""
