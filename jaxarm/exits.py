"""Exit statuses shared by the library (jaxarm.runner) and its commands (experiments), declared once: a command
a signal ended exits as a shell reports one a signal killed, with 128 + the signal's number (`experiments.start_up`,
which must not import jaxarm, follows the same rule)."""

import signal

STOPPED_BY_SIGNAL = 128 + signal.SIGINT
"""The exit status of a command stopped by Ctrl-C or SIGTERM (130); the checkpoints it saved are kept."""
