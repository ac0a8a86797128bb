"""The one exception type whose message is shown to the user as is (one line, says what to do)."""


class DanceNetError(Exception):
    """A problem with the user's input or setup, with a message fit to show in a UI or terminal."""


def first_line(e: BaseException, limit: int = 200) -> str:
    """The first line of a library's exception message (or its type when it has none), for a one-line error."""
    lines = str(e).strip().splitlines()
    return (lines[0] if lines else type(e).__name__)[:limit]


class GenerationCancelled(Exception):
    """The user cancelled a generation; nothing was produced."""
