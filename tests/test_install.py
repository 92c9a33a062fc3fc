"""The install: which Python the Makefile builds .venv with (tools/find_python.sh, run against
fake interpreters), and the torch requirement of the package against the tested version."""
import os
import re
import shutil
import subprocess
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FIND = ROOT / "tools" / "find_python.sh"
SH = shutil.which("sh") or "/bin/sh"


def fake_bin(tmp_path: Path, interpreters: dict[str, str | None]) -> Path:
    """A folder of fake interpreters: each prints its "MAJOR.MINOR" (None: fails, as a pyenv
    shim of a version not selected does)."""
    d = tmp_path / f"bin{len(list(tmp_path.glob('bin*')))}"
    d.mkdir()
    for name, version in interpreters.items():
        body = "echo 'not selected' >&2; exit 127" if version is None else f"echo {version}"
        (d / name).write_text(f"#!{SH}\n{body}\n")
        (d / name).chmod(0o755)
    return d


def find(tmp_path, interpreters, *args):
    d = fake_bin(tmp_path, interpreters)
    r = subprocess.run([SH, str(FIND), *args], capture_output=True, text=True, env={"PATH": str(d)})
    return r.returncode, r.stdout.strip(), r.stderr.strip()


@pytest.mark.parametrize("interpreters, chosen", [
    ({"python3.13": "3.13", "python3.12": "3.12", "python3": "3.11"}, "python3.13"),
    ({"python3.12": "3.12", "python3.11": "3.11"}, "python3.12"),
    ({"python3.13": None, "python3.11": "3.11"}, "python3.11"),     # a shim that does not run is skipped
    ({"python3.13": "3.10", "python3": "3.12"}, "python3"),         # a name that lies about its version too
    ({"python3": "3.11"}, "python3"),
    ({"python3": "4.0"}, "python3"),
])
def test_first_recent_enough_python_on_path(tmp_path, interpreters, chosen):
    assert find(tmp_path, interpreters) == (0, chosen, "")


def test_no_recent_python_is_one_error_line(tmp_path):
    rc, out, err = find(tmp_path, {"python3": "3.10", "python3.11": None})
    assert (rc, out) == (1, "")
    assert err.startswith("error: no Python >= 3.11 on PATH") and "PYTHON=" in err and "\n" not in err


def test_python_given_is_used_alone(tmp_path):
    interpreters = {"python3.13": "3.13", "python3.12": "3.12", "old": "3.10", "shim": None}
    assert find(tmp_path, interpreters, "python3.12") == (0, "python3.12", "")
    rc, out, err = find(tmp_path, interpreters, "old")
    assert (rc, out, err) == (1, "", "error: PYTHON=old is Python 3.10; 3.11 or newer is required")
    rc, out, err = find(tmp_path, interpreters, "shim")
    assert rc == 1 and err.startswith("error: PYTHON=shim does not run")
    rc, out, err = find(tmp_path, interpreters, "python3.9")
    assert rc == 1 and err.startswith("error: PYTHON=python3.9 not found")


@pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")
@pytest.mark.parametrize("args, chosen", [(["PYTHON=python3.12"], "python3.12"), ([], "python3.13")])
def test_make_builds_the_venv_with_the_python_found(tmp_path, args, chosen):
    """``make -n test`` in a checkout without .venv prints the venv command of the chosen Python."""
    work = tmp_path / "checkout"
    work.mkdir()
    for name in ("Makefile", "constraints.txt", "pyproject.toml"):
        shutil.copy(ROOT / name, work / name)
    shutil.copytree(ROOT / "tools", work / "tools")
    d = fake_bin(tmp_path, {"python3.13": "3.13", "python3.12": "3.12"})
    env = {**os.environ, "PATH": f"{d}{os.pathsep}{os.path.dirname(SH)}"}
    r = subprocess.run([shutil.which("make"), "-n", "test", *args], cwd=work, capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert f"{chosen} -m venv .venv" in r.stdout.splitlines()
    assert "-c constraints.txt" in r.stdout


def test_torch_is_a_range_in_the_package_and_pinned_in_the_constraints():
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    torch_req = [d for d in deps if re.match(r"torch\b", d)]
    assert torch_req == ["torch>=2.13,<3"]
    pins = [line.split("#")[0].strip() for line in (ROOT / "constraints.txt").read_text().splitlines()]
    assert "torch==2.13.0" in pins
    import torch
    from packaging.specifiers import SpecifierSet
    from packaging.version import Version

    # the torch the suite runs with lies inside the package's range
    assert Version(torch.__version__) in SpecifierSet(">=2.13,<3")


def test_the_package_version_is_one_number_everywhere():
    import neuroimagery

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    cited = re.search(r"^version:\s*(\S+)", (ROOT / "CITATION.cff").read_text(), re.M).group(1)
    assert neuroimagery.__version__ == project == cited
