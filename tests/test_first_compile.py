"""A loop compiled (not read from numba's cache) says so once per process, in a note: line."""
import pytest

from neuroimagery.nn import compiled


@pytest.mark.skipif(not compiled.installed(), reason="numba is not installed")
def test_a_first_compile_says_so_once(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # read when a cache is made: an empty one
    monkeypatch.setattr(compiled, "_said", type(compiled._said)())

    def _add(a, b):
        return a + b

    def _sub(a, b):
        return a - b

    kernels = compiled.Kernels({"_add": _add, "_sub": _sub})
    assert kernels("add")(2, 3) == 5 and kernels("sub")(3, 2) == 1
    err = capsys.readouterr().err
    assert err.count("note: compiling the package's numba loops") == 1, err
