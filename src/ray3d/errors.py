"""The one exception type for bad input: a ValueError whose message names the offending field and problem."""

from __future__ import annotations

import functools
from collections.abc import Iterable, Mapping


class InputError(ValueError):
    """Raised for input that is malformed, non-finite, wrongly shaped or physically impossible.

    ``arguments`` names the parameters (of the function the caller called) that would settle the problem, e.g.
    ``("overwrite",)``; the message states them in Python's terms, and the command line names its own flags
    for them instead (``message_for``)."""

    def __init__(self, message: str, arguments: tuple[str, ...] = ()):
        super().__init__(message)
        self.message, self.arguments = message, tuple(arguments)

    def __str__(self) -> str:
        return self.message_for({})

    def message_for(self, names: dict[str, str]) -> str:
        """The message, each argument called by its name in ``names`` (e.g. ``{"overwrite": "--force"}``) or,
        without one, as the Python parameter it is."""
        if not self.arguments:
            return self.message
        if all(a in names for a in self.arguments):
            return f"{self.message} ({', '.join(names[a] for a in self.arguments)})"
        label = "argument" if len(self.arguments) == 1 else "arguments"
        return f"{self.message} ({label}: {', '.join(self.arguments)})"


def reads_file(what: str):
    """Decorate a reader whose first argument is a path: anything but an ``InputError`` escaping it (a
    ``KeyError`` from a missing field, a ``TypeError`` from a wrong type, OpenCV's or zlib's errors on a corrupt
    file, ...) becomes an ``InputError`` naming the file, so a bad file never ends in a traceback."""

    def decorate(reader):
        @functools.wraps(reader)
        def read(path, *args, **kwargs):
            try:
                return reader(path, *args, **kwargs)
            except InputError:
                raise
            except RecursionError:
                raise InputError(f"{path}: nested too deeply to be a {what}") from None
            except Exception as err:  # the file boundary: whatever a malformed file makes the parsers raise
                detail = str(err).strip().splitlines()[0][:200] if str(err).strip() else ""
                raise InputError(f"{path}: not a readable {what} "
                                 f"({type(err).__name__}{': ' + detail if detail else ''})") from None
        return read

    return decorate


def missing_fields(document, fields: Iterable[str], where: str) -> list[str]:
    """The ``fields`` a JSON object read from ``where`` lacks (each reader words its own refusal of them); anything
    but an object refused here, in one line."""
    if not isinstance(document, Mapping):
        raise InputError(f"{where}: expected a JSON object, got {type(document).__name__}")
    return [name for name in fields if name not in document]
