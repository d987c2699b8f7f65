"""Exit statuses shared by the library (jaxarm.runner) and its commands (experiments), declared once. Imports
nothing: `experiments.start_up` reads it before JAX and its libraries load."""

STOPPED_BY_SIGNAL = 130
"""The exit status of a command stopped by Ctrl-C or SIGTERM (128 + SIGINT, as a shell reports it); the
checkpoints it saved are kept."""
OUTPUT_CLOSED = 141
"""The exit status of a command whose output's reader went away (`| head -1`): 128 + SIGPIPE, as a shell reports
any other command a closed pipe ended."""
