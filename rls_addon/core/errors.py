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


class OutputExists(OutputError):
    """Files a run would write are there already (``paths``) and it may not replace
    them: each entry point says how to allow it (--overwrite, the Overwrite option)."""

    def __init__(self, message, paths):
        super().__init__(message)
        self.paths = list(paths)


class RegionError(RLSError):
    """A region of interest (InfraLOB) is invalid or holds no points."""


class SettingsError(RLSError, ValueError):
    """A setting has a value that is not one of its choices or out of its range."""


class CastingError(RLSError):
    """A ray-casting backend cannot be built or used here."""


class InputError(RLSError):
    """An input file (point cloud, sidecar, polygon) is missing or malformed."""


class Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP (kill, SLURM, Kubernetes, systemd), raised where Ctrl-C raises
    KeyboardInterrupt, so a run stops the same way; ``exit_code`` is 128 + the signal's
    number, as a shell reports a process the signal ended."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = int(signum)
        self.exit_code = 128 + self.signum


def interrupt_exit_code(exc):
    """The exit code of a run stopped by ``exc``: 130 for Ctrl-C, 128 + N for signal N."""
    return getattr(exc, "exit_code", 130)
