"""The one exception type for bad scene input."""

from __future__ import annotations


class SceneError(ValueError):
    """Bad scene input: names the file, the 1-based line (0 when not about one line) and what was expected.

    ``str(err)`` reads ``path:line: message`` so a CLI can print it as one line.
    """

    def __init__(self, path: str | None, line: int, message: str):
        self.path = str(path) if path is not None else "<input>"
        self.line = int(line)
        self.message = message
        where = f"{self.path}:{self.line}" if self.line > 0 else self.path
        super().__init__(f"{where}: {message}")
