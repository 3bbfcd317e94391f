"""tools/llama_wheel.py: the version it builds is the one pyproject pins, without AMX on x86."""

import importlib.util
import platform
from pathlib import Path

import pytest

TOOL = Path(__file__).resolve().parent.parent / "tools" / "llama_wheel.py"


@pytest.fixture(scope="module")
def tool():
    spec = importlib.util.spec_from_file_location("llama_wheel", TOOL)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_pinned_version_is_the_one_installed(tool):
    version = tool.pinned_version()
    assert version.count(".") >= 2
    llama_cpp = pytest.importorskip("llama_cpp")
    assert llama_cpp.__version__ == version  # make setup installed what the tool builds


def test_amx_is_turned_off_on_x86_and_the_callers_arguments_are_kept(tool, monkeypatch):
    monkeypatch.setenv("CMAKE_ARGS", "-DGGML_OPENMP=ON")
    args = tool.cmake_args()
    assert args.startswith("-DGGML_OPENMP=ON")
    if platform.machine().lower() in ("x86_64", "amd64"):
        for flag in ("-mno-amx-tile", "-mno-amx-int8", "-mno-amx-bf16"):
            assert args.count(flag) == 2  # C and C++
    else:
        assert "amx" not in args


def test_flags_the_build_needs_are_not_silently_replaced(tool, monkeypatch):
    if platform.machine().lower() not in ("x86_64", "amd64"):
        pytest.skip("AMX flags are added on x86 only")
    monkeypatch.setenv("CMAKE_ARGS", "-DGGML_OPENMP=ON -DCMAKE_CXX_FLAGS='-O3'")
    with pytest.raises(SystemExit, match="CMAKE_CXX_FLAGS"):
        tool.cmake_args()


def test_only_wheels_for_this_interpreter_and_machine_are_reused(tool):
    import sys

    here = f"cp{sys.version_info.major}{sys.version_info.minor}"
    machine = platform.machine().lower()
    assert tool.usable(Path(f"llama_cpp_python-0.3.36-py3-none-linux_{machine}.whl"))
    assert tool.usable(Path(f"llama_cpp_python-0.3.36-{here}-{here}-manylinux_2_17_{machine}.whl"))
    assert not tool.usable(Path(f"llama_cpp_python-0.3.36-cp29-cp29-linux_{machine}.whl"))
    assert not tool.usable(Path("llama_cpp_python-0.3.36-py3-none-linux_someothercpu.whl"))


def test_the_installed_build_has_no_amx_kernels():
    llama_cpp = pytest.importorskip("llama_cpp")
    assert "AMX_INT8 = 1" not in llama_cpp.llama_print_system_info().decode()
