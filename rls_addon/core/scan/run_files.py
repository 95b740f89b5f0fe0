"""The files of a run's plan on disk (``plan``: a run's [(frame, SensorJob)], ``writer``
its ``run.Writer``): what each scan writes (``files_of``, ``planned``), checked before
anything is scanned (``distinct_outputs``: no two scans share a file; ``free_outputs``:
none is there yet, without --overwrite or --resume), what a killed run left
(``remove_leftovers``), what is complete now (``complete_on_disk``) and the disk budget
of the scans still to write (``disk_budget``)."""

import os


def files_of(writer, job, frame):
    """The files a scan of ``job`` at ``frame`` writes, its cloud first."""
    planned_files = getattr(writer, "planned_files", None)
    out = job.settings.output
    return planned_files(job.name, out, frame) if planned_files is not None \
        else [writer.path(job.name, out, frame)]


def planned(plan, writer):
    """(frame, job, files) of every step: the files a writer says a scan writes."""
    for frame, job in plan:
        yield frame, job, files_of(writer, job, frame)


def distinct_outputs(plan, writer):
    """Every scan writes files of its own, decided before any work: two LiDARs whose
    names give the same file names (names that differ only in characters a file
    name cannot hold), or a file name template without {frame} over several frames,
    end the run here, naming them. Writers of one file per run (a bag) say so
    (``per_scan = False``)."""
    from ..errors import OutputError

    if not getattr(writer, "per_scan", True):
        return
    owner = {}
    for frame, job, files in planned(plan, writer):
        for path in files:
            key = os.path.abspath(os.fspath(path))
            first = owner.setdefault(key, (frame, job))
            if first == (frame, job):
                continue
            f0, j0 = first
            if j0.name != job.name:
                raise OutputError(
                    f"LiDARs '{j0.name}' and '{job.name}' would write the same file "
                    f"{path} (their names give the same file name): rename one, or give "
                    "it an output folder or file name template of its own")
            raise OutputError(
                f"{job.name}'s file name template {job.settings.output.template!r} gives "
                f"the same file {path} for frames {f0} and {frame}: put {{frame}} in it "
                "(e.g. --template '{scene}_{sensor}_{frame:06d}'), or scan one frame")


def free_outputs(plan, writer):
    """Without --overwrite or --resume, an existing file of this run is an error
    before anything is scanned (pieces run again after a failed worker then keep
    what they wrote the first time)."""
    from ..errors import OutputExists

    existing = [p for _, _, files in planned(plan, writer) for p in files if os.path.exists(p)]
    if existing:
        more = f" (and {len(existing) - 1} more of this run's files)" if len(existing) > 1 else ""
        raise OutputExists(f"{existing[0]} already exists{more}; pass --overwrite to replace "
                           "it or --resume to keep it", existing)


def remove_leftovers(plan, writer):
    """Remove what a killed process left of this run's outputs: temporaries of
    writes in progress (``io.atomic``: a SIGKILL, a lost node or a dead worker can
    leave one) and the files of a scan whose last file was never written (a cloud
    without its sidecar); those scans are then done again. Only for runs that may
    replace their outputs (--resume, --overwrite) and once every worker stopped."""
    from ..output.io.atomic import stale_temporaries

    incomplete = getattr(writer, "incomplete", None)
    files = []
    for frame, job in plan:
        out = job.settings.output
        if incomplete is not None:
            for path in incomplete(job.name, out, frame):
                _unlink(path)
        files += writer.planned_files(job.name, out, frame)
    for tmp in stale_temporaries(files):
        _unlink(tmp)


def complete_on_disk(plan, writer):
    """How many scans of the plan have all their files, complete, now."""
    incomplete = getattr(writer, "incomplete", None)
    done = 0
    for frame, job, files in planned(plan, writer):
        if all(os.path.isfile(p) for p in files) and not (
                incomplete is not None and incomplete(job.name, job.settings.output, frame)):
            done += 1
    return done


def disk_budget(plan, writer):
    """The run's ``DiskBudget``: per sensor, the scans whose files are not there yet
    (a --resume keeps the others, an --overwrite replaces them in place; without
    either, ``free_outputs`` made sure none is there: no file is looked at again)."""
    from .disk_budget import DiskBudget

    remaining = {}
    if getattr(writer, "resume", False) or getattr(writer, "overwrite", False):
        for _, job, files in planned(plan, writer):
            if not all(os.path.isfile(p) for p in files):
                remaining[job.name] = remaining.get(job.name, 0) + 1
    else:
        for _, job in plan:
            remaining[job.name] = remaining.get(job.name, 0) + 1
    return DiskBudget(remaining)


def _unlink(path):
    try:
        os.unlink(path)
    except OSError:
        pass
