"""neuroimagery: neurorobotic models of mental imagery (mental rotation and tool use) on a
simulated iCub, built from population-coded maps with local learning rules in PyTorch."""

__version__ = "1.0.0"


def _writable(path: str) -> bool:
    """Whether folder ``path`` can be written, or made where its nearest existing parent can."""
    import os

    while not os.path.exists(path):
        parent = os.path.dirname(path)
        if parent == path:
            return False
        path = parent
    return os.path.isdir(path) and os.access(path, os.W_OK)


def _matplotlib_folder() -> None:
    """Point matplotlib's configuration and cache at a temporary folder when their places under HOME
    cannot be written (a read-only or missing home on a cluster node): matplotlib would do the same,
    but with two warnings on stderr before the run's own lines."""
    import os

    if os.environ.get("MPLCONFIGDIR"):
        return
    home = os.path.expanduser("~")
    places = (os.environ.get("XDG_CONFIG_HOME") or os.path.join(home, ".config"),
              os.environ.get("XDG_CACHE_HOME") or os.path.join(home, ".cache"))
    if all(_writable(os.path.join(p, "matplotlib")) for p in places):
        return
    import atexit
    import shutil
    import tempfile

    folder = tempfile.mkdtemp(prefix="neuroimagery-matplotlib-")
    os.environ["MPLCONFIGDIR"] = folder
    atexit.register(shutil.rmtree, folder, True)


_matplotlib_folder()
