"""One module per ``fydpad`` subcommand, each exposing ``register(subparsers)``.

``register`` adds the subcommand's parser and sets ``func`` to a callable taking the
parsed arguments and returning the exit code.
"""
