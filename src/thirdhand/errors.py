"""Exception hierarchy of thirdhand.

Every error a user can cause by bad input derives from :class:`ThirdhandError`,
so the CLI can print it on one line and exit non-zero without a traceback.
"""

from __future__ import annotations

import os


class ThirdhandError(Exception):
    """Base class of every error raised for a user's bad input."""


class DemonstrationError(ThirdhandError, ValueError):
    """A demonstration's arrays or metadata are inconsistent.

    The message names the body, the frame and the problem.
    """


class FormatError(ThirdhandError, ValueError):
    """A file could not be read: its content does not follow the format.

    Parameters
    ----------
    path : str or os.PathLike
        The file that was being read.
    message : str
        What was expected and what was found.
    line : int, optional
        1-based line number in the file, when the format is line based.
    where : str, optional
        Any other location (a frame, a body, a topic, a column).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        message: str,
        *,
        line: int | None = None,
        where: str | None = None,
    ) -> None:
        self.path = os.fspath(path)
        self.line = line
        self.where = where
        self.message = message
        loc = self.path
        if line is not None:
            loc += f" line {line}"
        if where is not None:
            loc += f" ({where})"
        super().__init__(f"{loc}: {message}")


class TaskFileError(ThirdhandError, ValueError):
    """A task file is invalid or could not be written."""


class OutputError(ThirdhandError, OSError):
    """An output cannot or may not be written.

    Raised when a command would write over one of its inputs, over an existing
    file without ``--force``, or when the write failed or was short (full disk,
    file-size limit); the previous file is then left as it was.
    """


class OptionError(ThirdhandError, ValueError):
    """A command-line option or a function argument is out of its range."""


class Terminated(BaseException):
    """Raised in the main thread on SIGTERM, so ``finally`` blocks (servers, temporaries) run."""
