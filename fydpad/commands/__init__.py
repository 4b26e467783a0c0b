"""One module per ``fydpad`` subcommand, each exposing ``register(subparsers)``.

``register`` adds the subcommand's parser and sets ``func`` to a callable taking the
parsed arguments and returning the exit code.

Why the imports inside the command functions: a module here imports its library only
where the command runs, so that ``fydpad --help`` and every subcommand's ``--help`` load
no NumPy, SciPy, OpenCV or matplotlib (``tests/cli/test_fast_help.py``; under 0.3 s).
"""
