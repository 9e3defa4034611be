"""The one exception type for bad input: a ValueError whose message names the offending field and problem."""


class InputError(ValueError):
    """Raised for input that is malformed, non-finite, wrongly shaped or physically impossible."""
