"""Click commands, one module per subcommand family; :mod:`driveid.cli` assembles them."""
