"""The command line ``saw-ros`` (``main``) and its subcommands (``commands``)."""
