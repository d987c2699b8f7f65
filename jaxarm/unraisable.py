"""Errors Python can only report as unraisable (in finalisers, exit handlers, coroutines left behind) where jaxarm
has already said what failed another way: kept off stderr, every other one reported as before."""

import sys
from collections.abc import Callable


def drop_unraisable(said: Callable[[BaseException], bool]) -> Callable[[], None]:
    """Routes `sys.unraisablehook` past the errors `said` accepts (each unraisable's `exc_value`); returns what puts
    the hook back as it was."""
    report = sys.unraisablehook

    def unless_said(unraisable) -> None:
        if not said(unraisable.exc_value):
            report(unraisable)

    sys.unraisablehook = unless_said
    return lambda: setattr(sys, "unraisablehook", report)
