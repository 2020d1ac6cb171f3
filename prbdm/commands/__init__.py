"""One module per ``prbdm`` subcommand: ``add_arguments(parser)`` and ``run(args) -> int``."""
