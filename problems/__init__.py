"""problems: plug-ins that turn scenes into mixed VIs, and the `mixvi` command line."""
