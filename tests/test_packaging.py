"""What a built wheel and sdist carry: the project's licence and each shipped real log's own, beside the
data they cover (issue of the licences that travel: the Panda log GPL-3.0, the Staubli TX40's Apache-2.0)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import tarfile
import zipfile

import pytest

from tests.conftest import ROOT

LICENSED = ("LICENSE", "harness/data/logs/panda_gaz2019/LICENSE", "harness/data/logs/staubli_tx40/LICENSE",
            "harness/data/logs/staubli_tx40/source/LICENSE-figaroh.txt")


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """The project's files copied out (a build writes into the tree it builds)."""
    copy = tmp_path_factory.mktemp("project") / "project"
    shutil.copytree(ROOT, copy, ignore=shutil.ignore_patterns(".venv", ".git", "reports", "build", "*.egg-info",
                                                              "__pycache__", ".pytest_cache", ".ruff_cache"))
    return copy


def test_every_licence_file_is_where_its_data_is():
    """The GPL-3.0 and Apache-2.0 texts as their licensors publish them, the root's the MIT licence
    pyproject.toml names."""
    assert (ROOT / "LICENSE").read_text().startswith("MIT License")
    assert "GNU GENERAL PUBLIC LICENSE" in (ROOT / LICENSED[1]).read_text()[:200]
    assert "Version 3, 29 June 2007" in (ROOT / LICENSED[1]).read_text()[:300]
    assert "Apache License" in (ROOT / LICENSED[2]).read_text()[:200]
    assert "Version 2.0" in (ROOT / LICENSED[2]).read_text()[:300]


@pytest.mark.slow  # a build in a fresh environment: setuptools fetched by pip
def test_the_wheel_and_the_sdist_carry_every_licence(source, tmp_path):
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(source)],
                   check=True)
    names = zipfile.ZipFile(next(tmp_path.glob("*.whl"))).namelist()
    assert all(path in names for path in LICENSED[1:]), names
    assert any(n.endswith(".dist-info/LICENSE") or n.endswith(".dist-info/licenses/LICENSE") for n in names)
    sdist = f"from setuptools import build_meta; build_meta.build_sdist({str(tmp_path)!r})"
    subprocess.run([sys.executable, "-c", sdist], check=True, cwd=source, capture_output=True)
    with tarfile.open(next(tmp_path.glob("*.tar.gz"))) as built:
        inside = [name.split("/", 1)[1] for name in built.getnames() if "/" in name]
    assert all(path in inside for path in LICENSED), inside
