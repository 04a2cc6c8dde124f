"""Subcommands of ``saw-ros``: one module each (see ``saw_ros/cli/main.py``)."""
