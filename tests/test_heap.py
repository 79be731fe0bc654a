"""glibc's heap thresholds raised once per process (harness/base/heap.py)."""

from __future__ import annotations

import platform
import subprocess
import sys

import pytest


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt's thresholds are glibc's")
def test_glibc_accepts_the_thresholds_where_its_own_rule_ends():
    """In a fresh process (this one may have set them already), mallopt accepts both values."""
    code = "from harness.base import heap; print(heap.keep_heap())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["True"]
