"""Command-line wrappers: a user's mistake becomes one line on stderr and exit status 2.

:func:`friendly_errors` wraps a task function; :func:`plain_hydra_errors` makes Hydra's own
refusals (a misspelt key, a value of the wrong type, a run directory that cannot be made) the
same kind of line instead of Hydra's few lines or traceback.
"""
from __future__ import annotations

import functools
import os
import re
import signal
import sys
import threading
from pathlib import Path

from ..core import console
from ..core.arguments import os_error_message
from ..core.errors import UserInputError


def _fail(message: str, log: bool = True) -> None:
    """``error: message`` on stderr, exit 2; ``log``: in the job log too (there is none before Hydra
    starts a job, and a sweep's own logging would print the line a second time, with a prefix)."""
    if log:
        console.error(message)
    else:
        print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


# run directories that Hydra made for this process's jobs (absolute path -> made by this job)
_MADE_BY_HYDRA: dict[str, bool] = {}


def _job_dir() -> Path | None:
    try:
        from hydra.core.hydra_config import HydraConfig

        return Path(HydraConfig.get().runtime.output_dir)
    except Exception:  # not under @hydra.main
        return None


def release_unclaimed_dir() -> None:
    """After a refusal: remove the run directory Hydra made for this job if the run never claimed
    it, i.e. it holds nothing but the job log and empty folders (the ``error:`` line on stderr is
    the record). A directory that existed before the job is left as it was."""
    d = _job_dir()
    if d is None or not _MADE_BY_HYDRA.get(os.path.abspath(d)):
        return
    try:
        entries = list(d.rglob("*"))
    except OSError:
        return
    logs = [p for p in entries if p.is_file() and p.parent == d and p.suffix == ".log"]
    if any(p.is_symlink() or (p.is_file() and p not in logs) for p in entries):
        return
    import logging

    for h in list(logging.getLogger().handlers):  # the job log's handler holds the file open
        if isinstance(h, logging.FileHandler) and Path(h.baseFilename).parent == d:
            h.close()
            logging.getLogger().removeHandler(h)
    try:
        for p in logs:
            p.unlink()
        for p in sorted((p for p in entries if p.is_dir()), key=lambda p: len(p.parts), reverse=True):
            p.rmdir()
        d.rmdir()
    except OSError:
        pass


def _terminate_as_interrupt(signum, frame):
    raise KeyboardInterrupt


def friendly_errors(fn):
    """Run ``fn``; print a :class:`UserInputError` or an ``OSError`` as ``error: ...`` and exit 2
    (tracebacks stay for bugs).

    SIGTERM is handled as SIGINT while ``fn`` runs (a ``KeyboardInterrupt`` in the main thread,
    so workers are stopped and finished files kept); the previous handler is restored after.
    """

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from ..core.workers import guard

        guard()  # a job of Hydra's joblib launcher ends with the process that launched it
        main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGTERM, _terminate_as_interrupt) if main else None
        try:
            return fn(*args, **kwargs)
        except UserInputError as e:
            console.error(str(e))
            release_unclaimed_dir()
            sys.exit(2)
        except OSError as e:
            console.error(os_error_message(e))
            release_unclaimed_dir()
            sys.exit(2)
        except KeyboardInterrupt:
            console.interrupted("interrupted: files already written in the run directory are kept")
            sys.exit(130)
        finally:
            if main:
                signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)

    return wrapper


def _one_line(ex: BaseException) -> str:
    """Hydra's and OmegaConf's multi-line messages as one line: what was given, then why."""
    parts = []
    for e in (ex, ex.__cause__):
        if e is None:
            continue
        for line in str(e).splitlines():
            line = line.strip()
            if line and not line.startswith(("object_type=", "Set the environment variable")) and line not in parts:
                parts.append(line)
    return "; ".join(parts) or type(ex).__name__


def missing_option_message(text: str) -> str | None:
    """Hydra's refusal of a group option that does not exist (``Could not find 'experiment/exp7'``,
    with its list of options and its search path) as one line: the option and the options there
    are, the schemas the options build on left out; None for other errors."""
    m = re.search(r"Could not find '([\w-]+)/([^']+)'", text)
    if m is None:
        return None
    group, option = m.groups()  # experiment, exp5/foo
    listed = re.search(r"Available options in '([^']+)':\n((?:\t.*\n?)*)", text)
    options = [o.strip() for o in (listed.group(2).splitlines() if listed else []) if o.strip()]
    options = [o for o in options if not o.endswith("_schema")]
    where = listed.group(1) if listed else group
    prefix = where[len(group) + 1:] + "/" if where.startswith(group + "/") else ""
    choose = f": choose one of {', '.join(prefix + o for o in options)}" if options else ""
    return f"{group}={option} is not an option of {group}{choose}"


_CLUSTER_HINT = ' (the submitit launchers need hydra-submitit-launcher: pip install -e ".[cluster]")'


def _refused_sweep_job(ex: Exception) -> str | None:
    """The ``error:`` line of a sweep job that a submitit launcher ran and the job refused (bad
    settings, a directory holding another run), with where submitit keeps the job's output; None
    for anything else (a job that crashed shows its traceback)."""
    if not type(ex).__module__.startswith("submitit"):
        return None
    text = str(ex)
    refusals = [ln[len("error: "):] for ln in text.splitlines() if ln.startswith("error: ")]
    if not refusals:
        return None
    where = re.search(r"with path (\S+)", text)
    log = f" (the job's output: {os.path.dirname(where.group(1))})" if where else ""
    return f"a job of the sweep stopped: {refusals[-1]}{log}"


def plain_hydra_errors() -> None:
    """Make Hydra report a configuration it cannot compose, or a run directory it cannot create,
    as one ``error:`` line with exit status 2 (``HYDRA_FULL_ERROR=1`` still shows Hydra's own); the
    same for a sweep job that the submitit launcher ran and that refused its settings."""
    from hydra._internal import utils as hydra_utils
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    original = getattr(hydra_utils.run_and_report, "__wrapped__", hydra_utils.run_and_report)

    @functools.wraps(original)
    def run_and_report(func):
        if os.environ.get("HYDRA_FULL_ERROR") == "1":
            return original(func)
        try:
            return func()
        except UserInputError as ex:
            _fail(str(ex), log=False)
        except (HydraException, OmegaConfBaseException) as ex:
            from ..config import unknown_key_message

            full = "\n".join(str(e) for e in (ex, ex.__cause__) if e is not None)  # object_type= names the schema
            unknown = unknown_key_message(full) or missing_option_message(full)
            if unknown:
                _fail(unknown, log=False)
            _fail(_one_line(ex) + (_CLUSTER_HINT if "hydra_submitit_launcher" in str(ex) else ""), log=False)
        except OSError as ex:
            _fail(os_error_message(ex), log=False)
        except Exception as ex:  # a bug: Hydra prints it as usual, without running anything again
            if "Unknown plugin class" in str(ex):  # hydra/launcher=... of a plugin that is not installed
                _fail(_one_line(ex) + (_CLUSTER_HINT if "hydra_submitit_launcher" in str(ex) else ""), log=False)
            refused = _refused_sweep_job(ex)
            if refused:
                _fail(refused, log=False)

            bug = ex

            def again():
                raise bug

            return original(again)

    hydra_utils.run_and_report = run_and_report
    _note_made_dirs()
    _refuse_empty_and_deleted()


def empty_or_deleted(override) -> str | None:
    """The refusal of a Hydra override that empties a setting (``key=''``, what an unset shell
    variable gives) or deletes it (``~key``), naming the key; None for any other override. Either
    would otherwise pass silently: a deleted setting takes its schema default again, an empty path
    reads as "not set"."""
    key = override.key_or_group
    if override.is_delete():
        return (f"~{key}: a setting cannot be deleted (it would silently take its default): give it a value "
                f"({key}=...) or leave it out")
    value = override.value() if not override.is_sweep_override() else None
    if isinstance(value, str) and not value.strip():
        return f"{key}={value!r} is empty (an unset shell variable?): give it a value, or leave it out for its default"
    return None


def _refuse_empty_and_deleted() -> None:
    """Refuse, as Hydra reads them (settings and groups, a single run or a sweep), the overrides
    :func:`empty_or_deleted` names."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    original = OverridesParser.parse_overrides
    original = getattr(original, "__wrapped__", original)

    @functools.wraps(original)
    def parse_overrides(self, overrides):
        parsed = original(self, overrides)
        for o in parsed:
            why = empty_or_deleted(o)
            if why:
                raise UserInputError(why)
        return parsed

    OverridesParser.parse_overrides = parse_overrides


def _note_made_dirs() -> None:
    """Record, before Hydra makes a job's run directory, whether it exists already
    (:func:`release_unclaimed_dir` removes only a directory made for the job)."""
    from hydra._internal import hydra as hydra_main
    from hydra._internal.core_plugins import basic_launcher
    from hydra.core import utils as hydra_core
    from omegaconf import OmegaConf

    original = getattr(hydra_core.run_job, "__wrapped__", hydra_core.run_job)

    @functools.wraps(original)
    def run_job(task_function, config, job_dir_key, job_subdir_key, *args, **kwargs):
        try:
            out = str(OmegaConf.select(config, job_dir_key))
            if job_subdir_key is not None:
                out = os.path.join(out, str(OmegaConf.select(config, job_subdir_key)))
            _MADE_BY_HYDRA[os.path.abspath(out)] = not os.path.exists(out)
        except Exception:  # unknown: the directory is then never removed
            pass
        return original(task_function, config, job_dir_key, job_subdir_key, *args, **kwargs)

    for mod in (hydra_core, hydra_main, basic_launcher):
        if getattr(mod, "run_job", None) is not None:
            mod.run_job = run_job
