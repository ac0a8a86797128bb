"""The one exception type whose message is shown to the user as is (one line, says what to do)."""


class DanceNetError(Exception):
    """A problem with the user's input or setup, with a message fit to show in a UI or terminal."""
