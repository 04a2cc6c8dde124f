"""What the outside sees (pure): the topic table and the msg_config parameter files."""
