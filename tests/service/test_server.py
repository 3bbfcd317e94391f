"""The service process's allocator settings: large blocks mapped on their own and one arena, where glibc allows it."""

import platform

import pytest

from globe.service import server


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc", reason="glibc only")
def test_glibc_takes_the_mmap_threshold_and_the_arenas():
    assert server.tune_allocator() is True


def test_a_c_library_without_mallopt_changes_nothing(monkeypatch):
    class NoMallopt:
        def __init__(self, name):
            pass

    monkeypatch.setattr(server.ctypes, "CDLL", NoMallopt)
    assert server.tune_allocator() is False
