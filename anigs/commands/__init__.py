"""One module per ``anigs`` subcommand: ``add_arguments(parser)`` and ``run(args) -> int``."""
