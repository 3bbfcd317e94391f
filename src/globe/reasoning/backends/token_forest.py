"""Exact batched continuation scoring on llama.cpp: a forest of token sequences, each node once.

The embedded backend asks "how likely is each candidate's text after this prompt?" thousands of
times. Every question is a small tree of tokens: the prompt, then each candidate's tokens. Many
questions share the start of their prompts, and candidates share their first words. Evaluated
as one *forest* (every distinct token prefix a node, decoded once, in a few batches), a question
costs a fraction of one decode per candidate token.

Batching is only allowed if it cannot change a score. In a default llama.cpp build a row's
logits depend on the other rows of its batch (tiled and repacked matrix kernels take over from
8 rows on; attention kernels change with the number of query rows and the cache length), so the
runtime is configured so that each row is computed by the same arithmetic whatever else is in
its batch or cache:

- flash attention, whose per-row kernel walks the visible cache cells in order and skips the
  others, so where a sequence's cells lie does not matter;
- no weight repacking (``use_extra_bufts`` off) and no tiled K-quant matmuls
  (``GGML_CPU_TILED_MM=0``): every matrix product is one dot product per output element;
- batches of 2 to 63 rows: 64 rows switch attention to a tiled kernel, and a single query row
  over 512 cache cells to a split one.

Whether this holds for the llama.cpp build at hand is *checked*, not assumed: at load, a probe
forest is scored both ways (batched, and each node on its own path: decoded again with its parent
and nothing else) and must agree to the bit, prompts past 256 tokens included. If it does not,
every question is scored node by node, which never depends on anything else asked (slower, the
same semantics). Either way a candidate's score depends only on
its prompt and its own text, so answers are reproducible, order-free and cacheable.
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
from typing import Iterator, Sequence

from globe.errors import LLMUnavailableError, MissingExtraError

log = logging.getLogger(__name__)

MAX_ROWS = 63  # rows per llama_decode: 64 query rows switch flash attention to a tiled kernel
MAX_LEAVES = 64  # sequence ids, one per leaf of a forest (llama.cpp keeps a logits row per id: 1 MB each)
MIN_CELLS = 1024  # cache cells of the runtime (a forest of several questions at once)


@dataclass(frozen=True, slots=True)
class Request:
    """A prompt's tokens (beginning with BOS) and the token lists whose log-probabilities after
    it are wanted (each at least one token)."""

    prompt: tuple[int, ...]
    tails: tuple[tuple[int, ...], ...]


@dataclass(slots=True)
class _Node:
    token: int
    pos: int
    parent: int  # -1 for the first token
    children: dict[int, int] = field(default_factory=dict)
    wanted: set[int] = field(default_factory=set)  # next tokens whose log-probability is read here
    leaves: list[int] = field(default_factory=list)


class Forest:
    """The distinct token prefixes of some requests (nodes), with the next tokens wanted after
    each. A node's key/value cells belong to every leaf below it (one sequence id per leaf), so
    under llama.cpp's mask each node sees exactly its own ancestors."""

    def __init__(self) -> None:
        self.nodes: list[_Node] = []
        self._roots: dict[int, int] = {}
        self.requests: list[tuple[Request, int, list[list[int]]]] = []  # (request, prompt end, tail paths)

    def _child(self, parent: int, token: int) -> int:
        table = self._roots if parent < 0 else self.nodes[parent].children
        node = table.get(token)
        if node is None:
            node = table[token] = len(self.nodes)
            self.nodes.append(_Node(token, 0 if parent < 0 else self.nodes[parent].pos + 1, parent))
        return node

    def growth(self, request: Request) -> tuple[int, int]:
        """(nodes, leaves) the forest would have with ``request`` added (nothing is changed)."""
        virtual: dict[tuple[int, int], int] = {}  # (parent, token) -> id of a node not there yet
        has_child: set[int] = set()

        def child(parent: int, token: int) -> int:
            if parent < len(self.nodes):
                table = self._roots if parent < 0 else self.nodes[parent].children
                if token in table:
                    return table[token]
            node = virtual.get((parent, token))
            if node is None:
                node = virtual[(parent, token)] = len(self.nodes) + len(virtual)
                has_child.add(parent)
            return node

        node = -1
        for tok in request.prompt:
            node = child(node, tok)
        end = node
        for tail in request.tails:
            cur = end
            for tok in tail[:-1]:
                cur = child(cur, tok)
        old_leaves = sum(1 for i, n in enumerate(self.nodes) if not n.children and i not in has_child)
        new_leaves = sum(1 for v in virtual.values() if v not in has_child)
        return len(self.nodes) + len(virtual), old_leaves + new_leaves

    def add(self, request: Request) -> None:
        node = -1
        for tok in request.prompt:
            node = self._child(node, tok)
        end = node
        paths = []
        for tail in request.tails:
            self.nodes[end].wanted.add(tail[0])
            path, cur = [end], end
            for depth in range(len(tail) - 1):
                cur = self._child(cur, tail[depth])
                self.nodes[cur].wanted.add(tail[depth + 1])
                path.append(cur)
            paths.append(path)
        self.requests.append((request, end, paths))

    def leaves(self) -> list[int]:
        return [i for i, n in enumerate(self.nodes) if not n.children]

    def order(self) -> list[int]:
        """Nodes by position (parents first; each sequence's positions consecutive across batches)."""
        return sorted(range(len(self.nodes)), key=lambda i: self.nodes[i].pos)

    def assign_sequences(self) -> int:
        """Give each leaf a sequence id and every node the ids of the leaves below it."""
        leaves = self.leaves()
        for seq, leaf in enumerate(leaves):
            node = leaf
            while node >= 0:
                self.nodes[node].leaves.append(seq)
                node = self.nodes[node].parent
        return len(leaves)


def batches(n: int, size: int = MAX_ROWS) -> list[tuple[int, int]]:
    """``range(n)`` in consecutive slices of at most ``size`` and (when n >= 2) at least 2 rows."""
    out, lo = [], 0
    while lo < n:
        hi = min(n, lo + size)
        if n - hi == 1:  # never leave a single row for last
            hi -= 1
        out.append((lo, hi))
        lo = hi
    return out


@contextlib.contextmanager
def _native_stderr_silenced() -> Iterator[None]:
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


class Runtime:
    """One llama.cpp model and context, configured for batch-invariant rows (see the module doc),
    with the lock every caller must hold (a llama.cpp context is not thread-safe). Runtimes live
    as long as the process (:func:`runtime` keeps them), so they are never freed by hand."""

    def __init__(self, path: str, n_threads: int, n_ctx: int) -> None:
        try:
            import llama_cpp
        except ImportError as err:
            raise MissingExtraError("llama-cpp-python", "llm") from err
        if not Path(path).is_file():
            raise LLMUnavailableError(f"model file does not exist: {path}")
        info = llama_cpp.llama_print_system_info().decode("utf-8", "replace")
        if "AMX_INT8 = 1" in info:
            raise LLMUnavailableError(
                "this llama-cpp-python was compiled with AMX kernels, which crash on some machines (a fault in "
                "ggml_backend_amx_mul_mat) and compute a row differently by batch; rebuild it without them: "
                "python tools/llama_wheel.py .wheels (what `make setup` runs)")
        # llama-cpp-python prints every llama.cpp log line unless its logger says otherwise
        logging.getLogger("llama-cpp-python").setLevel(logging.ERROR)
        # Read once per process by ggml at its first matrix product: one dot product per element.
        os.environ["GGML_CPU_TILED_MM"] = "0"
        self._llama = llama_cpp
        self.lock = threading.Lock()
        self.n_ctx = n_ctx
        self.cells = max(n_ctx, MIN_CELLS)
        log.info("loading %s with %d threads", path, n_threads)
        with _native_stderr_silenced():  # llama.cpp writes load notices past any log setting
            llama_cpp.llama_backend_init()
            mparams = llama_cpp.llama_model_default_params()
            mparams.use_extra_bufts = False  # no repacked weights: no 4-row kernels
            self.model = llama_cpp.llama_model_load_from_file(str(path).encode("utf-8"), mparams)
            if not self.model:
                raise LLMUnavailableError(f"llama.cpp could not load {path}")
            cparams = llama_cpp.llama_context_default_params()
            cparams.n_ctx = self.cells
            cparams.n_batch = max(MAX_ROWS, MAX_LEAVES)  # llama.cpp keeps one logits row per sequence id
            cparams.n_ubatch = MAX_ROWS
            cparams.n_seq_max = MAX_LEAVES
            cparams.kv_unified = True
            cparams.swa_full = True
            cparams.flash_attn_type = llama_cpp.LLAMA_FLASH_ATTN_TYPE_ENABLED
            cparams.n_threads = cparams.n_threads_batch = n_threads
            cparams.no_perf = True
            self.ctx = llama_cpp.llama_init_from_model(self.model, cparams)
            if not self.ctx:
                raise LLMUnavailableError("llama.cpp could not create a context")
        self.vocab = llama_cpp.llama_model_get_vocab(self.model)
        self.n_vocab = llama_cpp.llama_vocab_n_tokens(self.vocab)
        self.memory = llama_cpp.llama_get_memory(self.ctx)
        self._batch = llama_cpp.llama_batch_init(MAX_ROWS, 0, MAX_LEAVES)
        self.decodes = self.rows = 0  # llama_decode calls and rows decoded (for tests and benchmarks)
        self.batched = self._probe()
        log.info("llama.cpp rows are %s", "batch-invariant: questions are scored as forests" if self.batched
                 else "NOT batch-invariant in this build: every node is scored on its own")

    # -- tokens -------------------------------------------------------------------------------

    def tokenize(self, text: str, add_bos: bool) -> list[int]:
        data = text.encode("utf-8")
        size = len(data) + 8
        buf = (self._llama.llama_token * size)()
        n = self._llama.llama_tokenize(self.vocab, data, len(data), buf, size, add_bos, False)
        if n < 0:
            size = -n
            buf = (self._llama.llama_token * size)()
            n = self._llama.llama_tokenize(self.vocab, data, len(data), buf, size, add_bos, False)
        return list(buf[:n])

    # -- decoding -----------------------------------------------------------------------------

    def _decode(self, rows: Sequence[tuple[int, int, Sequence[int], bool]]) -> None:
        """One llama_decode of ``rows`` (token, position, sequence ids, whether logits are read)."""
        b = self._batch
        for i, (tok, pos, seqs, logits) in enumerate(rows):
            b.token[i] = tok
            b.pos[i] = pos
            b.n_seq_id[i] = len(seqs)
            ids = b.seq_id[i]
            for j, s in enumerate(seqs):
                ids[j] = s
            b.logits[i] = logits
        b.n_tokens = len(rows)
        self.decodes += 1
        self.rows += len(rows)
        rc = self._llama.llama_decode(self.ctx, b)
        if rc != 0:
            raise LLMUnavailableError(f"llama_decode failed ({rc})")

    def _log_probs(self, row: int, tokens: set[int]) -> dict[int, float]:
        """Log-probabilities of ``tokens`` from the logits of batch row ``row``: the exponentials
        in float32, summed in float64 (the normaliser over 262k words costs a fifth of a decode
        otherwise)."""
        import numpy as np

        ptr = self._llama.llama_get_logits_ith(self.ctx, row)
        logits = np.ctypeslib.as_array(ptr, shape=(self.n_vocab,))
        top = logits.max()
        lse = float(top) + math.log(float(np.exp(logits - top).sum(dtype=np.float64)))
        return {tok: float(logits[tok]) - lse for tok in tokens}

    def fits(self, request: Request) -> bool:
        """Whether :meth:`score` can take ``request`` (its prompt and tails fit the context)."""
        try:
            self._check(request)
        except ValueError:
            return False
        return True

    def _check(self, request: Request) -> None:
        longest = len(request.prompt) + max((len(t) for t in request.tails), default=0)
        if longest >= min(self.n_ctx, self.cells - MAX_ROWS) - 16:
            raise ValueError(f"prompt of {len(request.prompt)} tokens and a tail of {longest - len(request.prompt)} "
                             f"do not fit n_ctx={self.n_ctx}")
        if not request.prompt or any(not t for t in request.tails):
            raise ValueError("a request needs a prompt and non-empty tails")

    def score(self, requests: Sequence[Request]) -> list[list[float]]:
        """For each request, the summed log-probability of each tail after its prompt. Call with
        :attr:`lock` held. Scores do not depend on what else is asked (see the module doc)."""
        for r in requests:
            self._check(r)
        if not self.batched:
            return [self._score_alone(r) for r in requests]
        parts = [(i, part) for i, r in enumerate(requests) for part in _split(r, self.cells)]
        scores: list[list[float]] = [[] for _ in requests]
        group: list[tuple[int, Request]] = []
        forest = Forest()
        for i, part in parts:
            if group and not _fits(forest, part, self.cells):
                self._flush(group, scores)
                group, forest = [], Forest()
            group.append((i, part))
            forest.add(part)
        if group:
            self._flush(group, scores)
        return scores

    def _flush(self, group: Sequence[tuple[int, Request]], scores: list[list[float]]) -> None:
        for (i, _), part_scores in zip(group, self._score_forest([part for _, part in group])):
            scores[i].extend(part_scores)

    def _score_forest(self, requests: Sequence[Request]) -> list[list[float]]:
        forest = Forest()
        for r in requests:
            forest.add(r)
        forest.assign_sequences()
        nodes = forest.nodes
        order = forest.order()
        probs: dict[int, dict[int, float]] = {}
        self._llama.llama_memory_clear(self.memory, True)
        for lo, hi in batches(len(order)):
            rows = [(nodes[i].token, nodes[i].pos, nodes[i].leaves, bool(nodes[i].wanted)) for i in order[lo:hi]]
            self._decode(rows)
            for j, i in enumerate(order[lo:hi]):
                if nodes[i].wanted:
                    probs[i] = self._log_probs(j, nodes[i].wanted)
        return [[_path_sum(probs, path, tail) for path, tail in zip(paths, r.tails)] for r, _, paths in forest.requests]

    def _score_alone(self, request: Request) -> list[float]:
        """Each node decoded with its own path only: the prompt in fixed batches, then the tails'
        nodes depth first, each decoded again with its parent (a node's ancestors are the cells
        in place, each computed the same way). Never one row alone: a single query row over 512
        cache cells or more takes another attention kernel than the forest's batches."""
        forest = Forest()
        forest.add(request)
        nodes = forest.nodes
        end = len(request.prompt) - 1  # the prompt's nodes come first, in order
        probs: dict[int, dict[int, float]] = {}
        self._llama.llama_memory_clear(self.memory, True)
        for lo, hi in batches(end + 1):
            self._decode([(nodes[i].token, nodes[i].pos, (0,), i == end) for i in range(lo, hi)])
        probs[end] = self._log_probs(self._batch.n_tokens - 1, nodes[end].wanted)
        stack = sorted(nodes[end].children.values(), reverse=True)
        while stack:
            i = stack.pop()
            parent = nodes[nodes[i].parent]
            self._llama.llama_memory_seq_rm(self.memory, 0, parent.pos, -1)
            self._decode([(parent.token, parent.pos, (0,), False), (nodes[i].token, nodes[i].pos, (0,), True)])
            probs[i] = self._log_probs(1, nodes[i].wanted)
            stack.extend(sorted(nodes[i].children.values(), reverse=True))
        return [_path_sum(probs, path, tail) for path, tail in zip(forest.requests[0][2], request.tails)]

    def _probe(self) -> bool:
        """Whether batched forests score exactly as nodes on their own in this build."""
        bos = self.tokenize("", True)
        words = [self.tokenize(w, False) for w in (" cereal bowl", " jam jar", " kitchen knife and fork", " cup",
                                                    " milk carton box", " plate", " toaster", " spoon")]
        head = self.tokenize("While making breakfast in the kitchen, the person used the pan, then the", False)
        long = self.tokenize(" spatula, then the bowl, then the cup. " * 6, False)
        longer = self.tokenize(" spatula, then the bowl, then the cup. " * 24, False)  # past 256 tokens
        requests = [Request(tuple(bos + head), tuple(map(tuple, words))),
                    Request(tuple(bos + head + words[0]), tuple(map(tuple, words[3:]))),
                    Request(tuple(bos + head + long), tuple(map(tuple, words[:5]))),
                    Request(tuple(bos + head + longer), tuple(map(tuple, words[2:])))]
        batched = self._score_forest(requests)
        alone = [self._score_alone(r) for r in requests]
        return batched == alone


def _split(request: Request, cells: int) -> list[Request]:
    """``request`` as consecutive parts of its tails, each with fewer leaves than a forest may
    hold (a leaf per distinct tail without its last token, at most) and nodes that fit ``cells``
    (a tail adds at most its tokens but the last)."""
    parts: list[Request] = []
    tails: list[tuple[int, ...]] = []
    keys: set[tuple[int, ...]] = set()
    budget = cells - MAX_ROWS - len(request.prompt)
    nodes = 0
    for tail in request.tails:
        key = tail[:-1]
        if key not in keys and tails and (len(keys) == MAX_LEAVES - 1 or nodes + len(key) > budget):
            parts.append(Request(request.prompt, tuple(tails)))
            tails, keys, nodes = [], set(), 0
        if key not in keys:
            keys.add(key)
            nodes += len(key)
        tails.append(tail)
    return parts + [Request(request.prompt, tuple(tails))]


def _fits(forest: Forest, request: Request, cells: int) -> bool:
    """Whether ``forest`` can take ``request`` too (nodes within the cache, leaves within the ids)."""
    nodes, leaves = forest.growth(request)
    return nodes <= cells - MAX_ROWS and leaves <= MAX_LEAVES


def _path_sum(probs: dict[int, dict[int, float]], path: list[int], tail: Sequence[int]) -> float:
    total = probs[path[0]][tail[0]]
    for depth in range(1, len(tail)):
        total += probs[path[depth]][tail[depth]]
    return total


_RUNTIMES_LOCK = threading.Lock()


def runtime(path: str, n_threads: int, n_ctx: int) -> Runtime:
    """One runtime per (file, threads, context) per process, loaded once even when several
    threads ask for it at the same time."""
    with _RUNTIMES_LOCK:
        return _runtime(path, n_threads, n_ctx)


@functools.lru_cache(maxsize=None)
def _runtime(path: str, n_threads: int, n_ctx: int) -> Runtime:
    return Runtime(path, n_threads, n_ctx)
