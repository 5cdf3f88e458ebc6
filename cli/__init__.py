"""photogram_cli: the `photogram` command line (installed from cli/)."""
