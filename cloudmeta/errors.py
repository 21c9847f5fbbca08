"""Exceptions raised at cloudmeta's boundary. Kernels never raise: input is validated once, here."""


class CloudmetaError(Exception):
    """Base class of every error cloudmeta raises on purpose."""


class InputError(CloudmetaError, ValueError):
    """A bad argument to the Python API. The message names the argument and, where it applies, the index."""


class OutputError(CloudmetaError, ValueError):
    """An output path that cannot or must not be written (checked before any work): names the path."""


class SceneError(CloudmetaError, ValueError):
    """A bad scene file: names the file, the key path (``media[0].balls[12].radius``) and what was expected."""

    def __init__(self, file, key_path, message):
        self.file = str(file) if file is not None else None
        self.key_path = key_path
        self.detail = message
        where = f"{self.file}: " if self.file else ""
        key = f"{key_path}: " if key_path else ""
        super().__init__(f"{where}{key}{message}")
