"""tools/llama_wheel.py: the version it builds is the one pyproject pins, for one instruction set
(x86-64-v3 wherever the CPU has it: the same kernels, so the same LLM answers, on every such
machine), never with AMX."""

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


def test_an_avx2_machine_builds_for_x86_64_v3_and_nothing_else(tool, monkeypatch):
    monkeypatch.delenv("CMAKE_ARGS", raising=False)
    v3 = {"sse4_2", "avx", "avx2", "fma", "f16c", "bmi2"}
    if platform.machine().lower() in ("x86_64", "amd64"):
        assert tool.variant(v3 | {"avx512f", "amx_tile"}) == tool.variant(v3) == "x86-64-v3"
        assert tool.variant({"sse4_2", "avx"}) == "x86-64-native"
    args = tool.cmake_args("x86-64-v3")
    for flag in ("-DGGML_NATIVE=OFF", "-DGGML_AVX2=ON", "-DGGML_FMA=ON", "-DGGML_AVX512=OFF", "-DGGML_AMX_INT8=OFF"):
        assert flag in args
    assert "GGML_NATIVE" not in tool.cmake_args("x86-64-native") and tool.cmake_args("native") == ""


def test_the_installed_build_runs_the_kernels_of_its_instruction_set(tool):
    """The kernels this machine runs are those of the build's instruction set, not of its CPU."""
    llama_cpp = pytest.importorskip("llama_cpp")
    info = llama_cpp.llama_print_system_info().decode()
    if tool.variant() == "x86-64-v3":
        assert "AVX2 = 1" in info and "AVX512" not in info and "AMX" not in info, info


@pytest.mark.llm
@pytest.mark.slow
def test_this_build_answers_as_the_build_that_made_the_reference_results(tool, gguf_path):
    """On an x86-64-v3 build (what make setup installs wherever the CPU has AVX2), the LLM's scores
    are bit for bit those of the build behind reference/homer_plus, so its LLM rows are too."""
    import subprocess
    import sys

    llama_cpp = pytest.importorskip("llama_cpp")
    info = llama_cpp.llama_print_system_info().decode()
    if tool.variant() != "x86-64-v3" or "AVX512 = 1" in info or "AMX" in info:
        pytest.skip(f"not an x86-64-v3 build ({tool.variant()}: {info.strip()[:80]})")
    done = subprocess.run([sys.executable, str(TOOL.parent / "llm_fingerprint.py"), str(gguf_path), "--threads", "2"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-500:] + done.stderr[-1500:]
    assert "the same as the build that made reference/homer_plus" in done.stdout
