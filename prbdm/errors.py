"""Exceptions shared by the library and the command line.

Every user-facing validation raises :class:`BadInput`; the CLI turns it into exit status 2 and one
line that names the field and the allowed range.
"""


class BadInput(ValueError):
    """Invalid user input (a beam file, a polygon, a flag). The message names the field."""
