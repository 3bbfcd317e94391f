"""Build llama-cpp-python for one instruction set (once, into a wheel folder) and install it into
the running interpreter's environment.

llama-cpp-python compiles llama.cpp with ``-march=native``: each machine gets the kernels of its
own CPU (AVX-512 on one, AVX2 on another, AMX tiles on a third), and kernels that sum in another
order give an LLM's scores that differ in their last bits, enough to flip the closest choices: a
table of LLM rows made on one machine was not the table another made. So on x86-64 with AVX2,
FMA and F16C (x86-64-v3: every x86 server of the last decade), the build names that instruction
set and nothing else (``GGML_NATIVE=OFF``; no AVX-512, no AMX, whose tile kernels also crashed
at the first prompt on some machines of this project's kind and make rows depend on the rest of
their batch): every such machine runs the same kernels and gives the same answers. An x86 CPU
without AVX2 gets a native build without AMX (its LLM rows may differ from the reference); other
CPUs build as llama-cpp-python does. The wheel is built once per machine kind (4-7 minutes on 2
cores) for the version pinned in pyproject.toml's ``llm`` extra, into a folder named by its
instruction set, and reused by every new virtual environment; ``make setup`` runs this before
installing the project. Usage: python tools/llama_wheel.py WHEEL_DIR
"""

from __future__ import annotations

import os
import platform
import re
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
AMX_OFF = "-mno-amx-tile -mno-amx-int8 -mno-amx-bf16"
V3_NEEDS = ("avx2", "fma", "f16c", "bmi2")  # x86-64-v3 (with AVX, SSE4.2, which it implies)
V3_ARGS = ("-DGGML_NATIVE=OFF -DGGML_SSE42=ON -DGGML_AVX=ON -DGGML_AVX2=ON -DGGML_FMA=ON -DGGML_F16C=ON "
           "-DGGML_BMI2=ON -DGGML_AVX_VNNI=OFF -DGGML_AVX512=OFF -DGGML_AVX512_VBMI=OFF -DGGML_AVX512_VNNI=OFF "
           "-DGGML_AVX512_BF16=OFF -DGGML_AMX_TILE=OFF -DGGML_AMX_INT8=OFF -DGGML_AMX_BF16=OFF")


def cpu_flags() -> set[str]:
    """The CPU's feature flags (Linux's /proc/cpuinfo; none where it cannot be read)."""
    try:
        text = Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace")
    except OSError:
        return set()
    return {flag for line in text.splitlines() if line.startswith("flags") for flag in line.split(":", 1)[1].split()}


def variant(flags: set[str] | None = None) -> str:
    """The instruction set this machine's build names: ``x86-64-v3``, ``x86-64-native`` (an x86 CPU
    without AVX2) or ``native`` (any other CPU)."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return "native"
    return "x86-64-v3" if set(V3_NEEDS) <= (cpu_flags() if flags is None else flags) else "x86-64-native"


def pinned_version() -> str:
    """The ``llama-cpp-python==X`` pin of the ``llm`` extra."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    for req in project["optional-dependencies"]["llm"]:
        match = re.fullmatch(r"llama-cpp-python(\[[^\]]*\])?==([\w.]+)", req.replace(" ", ""))
        if match:
            return match.group(2)
    sys.exit("pyproject.toml: the llm extra pins no llama-cpp-python==VERSION")


def cmake_args(kind: str | None = None) -> str:
    """CMAKE_ARGS for the build: the caller's, plus the instruction set of ``kind`` (default: this
    machine's :func:`variant`) on x86 (the flags exist only there)."""
    args = os.environ.get("CMAKE_ARGS", "")
    kind = variant() if kind is None else kind
    if kind.startswith("x86-64"):
        if re.search(r"-DCMAKE_(C|CXX)_FLAGS\b", args):  # CMake keeps the last -D: one would be lost
            sys.exit("CMAKE_ARGS sets CMAKE_C_FLAGS or CMAKE_CXX_FLAGS, which this build needs for "
                     f"'{AMX_OFF}': add those flags to yours and build with pip yourself, or unset them")
        args += f" -DCMAKE_C_FLAGS='{AMX_OFF}' -DCMAKE_CXX_FLAGS='{AMX_OFF}'"
        if kind == "x86-64-v3":
            args += " " + V3_ARGS
    return args.strip()


def usable(wheel: Path) -> bool:
    """Whether ``wheel`` (name-version[-build]-python-abi-platform.whl) installs into this
    interpreter: a wheel folder may hold builds for other Pythons or machines."""
    python, abi, plat = wheel.name[:-len(".whl")].split("-")[-3:]
    here = f"cp{sys.version_info.major}{sys.version_info.minor}"
    return (any(tag in ("py3", here) for tag in python.split("."))
            and any(tag in ("none", "abi3", here) for tag in abi.split("."))
            and any(tag == "any" or tag.endswith(platform.machine().lower()) for tag in plat.split(".")))


def main() -> None:
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    kind = variant()
    wheels = Path(sys.argv[1]).resolve() / kind  # a wheel of another instruction set is never reused
    version = pinned_version()
    built = sorted(w for w in wheels.glob(f"llama_cpp_python-{version}-*.whl") if usable(w))
    if not built:
        wheels.mkdir(parents=True, exist_ok=True)
        print(f"building llama-cpp-python {version} for {kind} into {wheels} (4-7 minutes, once)", flush=True)
        subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-cache-dir", "--no-binary",
                        "llama-cpp-python", "-w", str(wheels), f"llama-cpp-python=={version}"],
                       env=dict(os.environ, CMAKE_ARGS=cmake_args()), check=True)
        built = sorted(w for w in wheels.glob(f"llama_cpp_python-{version}-*.whl") if usable(w))
        if not built:
            sys.exit(f"pip reported success but left no llama_cpp_python-{version} wheel in {wheels}")
    # --force-reinstall: an environment may hold a build of the same version with AMX kernels
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--force-reinstall", str(built[-1])],
                   check=True)


if __name__ == "__main__":
    main()
