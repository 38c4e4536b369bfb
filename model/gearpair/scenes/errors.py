"""What a scene can raise or warn: `SceneError` (a ``ValueError`` naming the file and the
key) and `SceneWarning`."""


class SceneWarning(UserWarning):
    """Something in a scene that is allowed but most likely not meant (e.g. an input-CSV
    column that no input uses: a misspelt name leaves that input at its default)."""


class SceneError(ValueError):
    """A scene file is invalid; the message names the file and the key."""
