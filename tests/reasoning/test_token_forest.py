"""Forests of token sequences: their structure (pure Python) and, on the real llama.cpp, that
batched scoring is exactly node-by-node scoring, whatever is batched together."""

import random

import pytest

from globe.errors import LLMUnavailableError
from globe.reasoning.backends.token_forest import MAX_LEAVES, MAX_ROWS, Forest, Request, _split, batches


def test_batches_cover_every_row_once_and_never_leave_one_alone():
    for n in range(0, 300):
        parts = batches(n)
        assert [i for lo, hi in parts for i in range(lo, hi)] == list(range(n))
        assert all(hi - lo <= MAX_ROWS for lo, hi in parts)
        if n >= 2:
            assert all(hi - lo >= 2 for lo, hi in parts)


def test_forest_shares_prefixes_and_gives_each_node_the_leaves_below_it():
    forest = Forest()
    forest.add(Request((2, 10, 11), ((20,), (21, 30), (21, 31, 40))))
    forest.add(Request((2, 10, 12), ((20, 50),)))
    # nodes: 2, 10, 11, 12 | after 11: 21, (21, 31) | after 12: 20
    assert len(forest.nodes) == 7
    tokens_at = {n.pos: set() for n in forest.nodes}
    for n in forest.nodes:
        tokens_at[n.pos].add(n.token)
    assert tokens_at == {0: {2}, 1: {10}, 2: {11, 12}, 3: {21, 20}, 4: {31}}
    n_leaves = forest.assign_sequences()
    assert n_leaves == len(forest.leaves()) == 2  # (11, 21, 31) and (12, 20)
    root = forest.nodes[0]
    assert sorted(root.leaves) == [0, 1]  # the shared start belongs to both
    for leaf_seq, leaf in enumerate(forest.leaves()):
        node = leaf
        while node >= 0:  # every ancestor of a leaf carries its sequence id, no other node does
            assert leaf_seq in forest.nodes[node].leaves
            node = forest.nodes[node].parent
    # the wanted next tokens: after the first prompt, 20 and 21; after (..11, 21): 30 and 31
    end = forest.requests[0][1]
    assert forest.nodes[end].wanted == {20, 21}
    order = forest.order()
    assert [forest.nodes[i].pos for i in order] == sorted(n.pos for n in forest.nodes)


def test_growth_predicts_nodes_and_leaves_without_changing_the_forest():
    rng = random.Random(0)
    for _ in range(200):
        forest = Forest()
        for _ in range(rng.randint(0, 4)):
            forest.add(_random_request(rng))
        request = _random_request(rng)
        before = len(forest.nodes)
        predicted = forest.growth(request)
        assert len(forest.nodes) == before
        forest.add(request)
        assert predicted == (len(forest.nodes), len(forest.leaves()))


def test_a_request_with_many_leaves_or_nodes_is_split_within_the_limits():
    tails = tuple((t, 1000 + t) for t in range(150)) + tuple((t,) for t in range(150, 160))
    long_tails = tuple(tuple(range(100 * t, 100 * t + 30)) for t in range(1, 12))  # 29 nodes each
    for request, cells in ((Request((2, 3), tails), 1024), (Request((2,) + tuple(range(3, 200)), long_tails), 512)):
        parts = _split(request, cells)
        assert len(parts) > 1
        assert [t for p in parts for t in p.tails] == list(request.tails)
        for part in parts:
            forest = Forest()
            forest.add(part)
            assert len(forest.leaves()) <= MAX_LEAVES
            assert len(forest.nodes) <= cells - MAX_ROWS


def _random_request(rng: random.Random) -> Request:
    prompt = (2,) + tuple(rng.randint(3, 6) for _ in range(rng.randint(0, 4)))
    tails = tuple(tuple(rng.randint(3, 6) for _ in range(rng.randint(1, 3))) for _ in range(rng.randint(1, 5)))
    return Request(prompt, tails)


# -- on the real runtime --------------------------------------------------------------------

@pytest.mark.llm
def test_this_build_is_batch_invariant(embedded_llm):
    """`make setup`'s llama.cpp passes the load-time probe, so questions are scored as forests."""
    assert embedded_llm._shared().batched


@pytest.mark.llm
def test_big_forests_over_many_batches_score_like_nodes_alone(embedded_llm, seed):
    """Many prompts with shared starts, candidates of 1-4 tokens, more leaves than one forest
    holds and more rows than one batch: every score equals its node-by-node reference."""
    rt = embedded_llm._shared()
    rng = random.Random(seed)
    words = ["cup", "coffee cup", "coffee filter", "food jam", "food cereal", "milk", "bowl", "tooth paste",
             "toothbrush", "deck of cards", "remote control", "laptop charger cable", "book", "pen"]
    tails = tuple(tuple(rt.tokenize(" " + w, False)) for w in words) + tuple(
        tuple(rt.tokenize(f" {w} {i} x", False)) for i in range(70) for w in words[:1])  # > 64 leaves
    requests = []
    for activity in ("cooking", "cleaning the kitchen", "reading"):
        for used in rng.sample(words, 4):
            text = f"While {activity}, the person used the {used}. Next, the person used the"
            prompt = tuple(rt.tokenize(text, True))
            requests.append(Request(prompt, tuple(rng.sample(tails, rng.randint(1, 8)))))
    requests.append(Request(requests[0].prompt, tuple(rng.sample(tails, len(tails)))))  # every tail: > 64 leaves
    requests.append(Request(requests[1].prompt, tuple(rng.sample(tails, 40))))  # with the one above: > one batch's rows
    assert any(len(_split(r, rt.cells)) > 1 for r in requests)  # some need several forests (whatever the seed)
    with rt.lock:
        decodes = rt.decodes
        batched = rt.score(requests)
        assert rt.decodes - decodes >= 2  # several batches
        alone = [rt._score_alone(r) for r in requests]
    assert batched == alone


@pytest.mark.llm
def test_scores_do_not_depend_on_the_thread_count(gguf_path, embedded_llm):
    from globe.reasoning.backends.token_forest import runtime

    rt2 = embedded_llm._shared()
    rt1 = runtime(str(gguf_path), 2 if embedded_llm.n_threads == 1 else 1, rt2.n_ctx)  # another runtime
    assert rt1 is not rt2
    prompt = "While cooking, the person used the pan. Next, the person used the"
    tails = tuple(tuple(rt2.tokenize(w, False)) for w in (" spatula", " coffee cup", " food jam"))
    request = Request(tuple(rt2.tokenize(prompt, True)), tails)
    with rt1.lock, rt2.lock:
        assert rt1.score([request]) == rt2.score([request])


def test_a_build_with_amx_kernels_is_refused_with_the_fix(monkeypatch, tmp_path):
    llama_cpp = pytest.importorskip("llama_cpp")
    from globe.reasoning.backends.token_forest import Runtime

    model = tmp_path / "model.gguf"
    model.write_bytes(b"GGUF")
    monkeypatch.setattr(llama_cpp, "llama_print_system_info", lambda: b"CPU : AVX2 = 1 | AMX_INT8 = 1 | ")
    with pytest.raises(LLMUnavailableError, match="tools/llama_wheel.py"):
        Runtime(str(model), 2, 512)
