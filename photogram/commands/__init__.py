"""Commands as library functions: each configures the one engine and
writes a results folder. The command line calls ``run(project, args)``."""
