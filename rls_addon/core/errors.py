"""Domain errors. Operators report them, the command line prints them on one line."""


class RLSError(Exception):
    """Base class for every error RLS raises on purpose; its message is for the user."""


class PresetError(RLSError):
    """A device preset file is missing, malformed or fails validation."""


class PatternError(RLSError):
    """A scan pattern cannot be generated from the given parameters or file."""


class SceneError(RLSError):
    """The scene cannot be scanned (no sensor, no geometry, bad object)."""


class OutputError(RLSError):
    """An output path is invalid, unwritable, or would overwrite a file."""


class RegionError(RLSError):
    """A region of interest (InfraLOB) is invalid or holds no points."""


class SettingsError(RLSError, ValueError):
    """A setting has a value that is not one of its choices or out of its range."""


class CastingError(RLSError):
    """A ray-casting backend cannot be built or used here."""


class InputError(RLSError):
    """An input file (point cloud, sidecar, polygon) is missing or malformed."""
