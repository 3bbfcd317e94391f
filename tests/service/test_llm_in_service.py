"""The embedded LLM in a real ``globe serve``: no request waits for the model to load, an answer
has a time limit, and a poisoned or unusable answer cache is the n-gram fallback (never a 500,
never a failed start)."""

import sqlite3
import time

import httpx
import pytest

from globe.config import Deployment, GlobeConfig
from globe.evaluation.online import day_observations, replay
from globe.session import build_session
from tests.service.conftest import REPLAY_ENV, at, upload, wait_for_llm

pytestmark = [pytest.mark.service, pytest.mark.llm]
ASK_ALWAYS = {**REPLAY_ENV, "GLOBE_LLM__BACKEND": "embedded", "GLOBE_LLM__N_THREADS": "1",
              "GLOBE_GATE__THRESHOLD": "1.0"}


def observe_until_consulted(c, h, limit: int = 60):
    """Observations of a test day, a prediction after each, until one consults the LLM: (its time
    in seconds, the prediction)."""
    day = h.test[0]
    for t in range(limit):
        c.observe("A", at(0, day.minutes[t]), day.activities[t], dict(zip(h.objects, day.locations[t])))
        started = time.perf_counter()
        p = c.prediction("A")
        if p.llm_consulted:
            return time.perf_counter() - started, p, t
    raise AssertionError("no prediction consulted the LLM")


def test_the_first_llm_prediction_after_a_start_does_not_wait_for_the_model(make_server, households, tmp_path):
    """The model loads (and is probed) in the background from start-up; meanwhile predictions
    answer at once with the n-gram choice (llm_fallback LLMUnavailableError). The first
    LLM-consulting prediction took 17-86 s, holding the household's lock, when it loaded the model."""
    srv = make_server({**ASK_ALWAYS, "GLOBE_LLM__CACHE_DIR": str(tmp_path / "cache")})
    h = households["A"]
    with srv.client() as c:
        upload(c, "A", h)
        seconds, first, t = observe_until_consulted(c, h)
        print(f"first LLM-consulting prediction after the start: {seconds * 1000:.0f} ms "
              f"(llm_fallback {first.llm_fallback}, model {httpx.get(srv.url + '/health').json()['llm']})")
        assert seconds < 3.0, seconds
        assert first.llm_fallback in (None, "LLMUnavailableError")
        assert c.prediction("A") == first  # a step's prediction is decided once
        wait_for_llm(srv.url)
        day = h.test[0]
        for u in range(t + 1, t + 40):  # the next steps, decided with the model loaded
            c.observe("A", at(0, day.minutes[u]), day.activities[u], dict(zip(h.objects, day.locations[u])))
            answered = c.prediction("A")
            if answered.llm_consulted:
                break
        assert answered.llm_consulted and answered.llm_fallback is None, answered


def test_the_embedded_answer_has_a_time_limit(make_server, households, tmp_path):
    srv = make_server({**ASK_ALWAYS, "GLOBE_SERVICE__LLM_TIMEOUT_S": "0.001"})
    h = households["A"]
    with srv.client() as c:
        upload(c, "A", h)
        wait_for_llm(srv.url)
        seconds, p, _ = observe_until_consulted(c, h)
        assert p.llm_fallback == "LLMTimeoutError" and seconds < 3.0, (p, seconds)
        assert c.stats("A")["llm_fallbacks"]["LLMTimeoutError"] >= 1


def test_a_poisoned_answer_cache_is_the_ngram_fallback_over_http(make_server, households, tmp_path):
    """The answer the last prediction stored is replaced by values of the wrong JSON type; after a
    restart the same question gets each as a 200 with llm_fallback LLMCacheError, and the
    connection keeps working (each 500 dropped it, failing the next requests too)."""
    cache = tmp_path / "cache"
    srv = make_server({**ASK_ALWAYS, "GLOBE_LLM__CACHE_DIR": str(cache)})
    h = households["A"]
    with srv.client() as c:
        upload(c, "A", h)
        wait_for_llm(srv.url)
        _, p, t = observe_until_consulted(c, h)
        assert p.llm_fallback is None
    # What the fallback must give: the n-gram's own choice at that step (not whatever the LLM said,
    # which depends on the machine's build of llama.cpp), from the same session without an LLM.
    config = GlobeConfig().with_overrides({"llm.backend": "none"})
    session = build_session(h, config, Deployment.configured(config, "ngram"), None)
    day = h.test[0]
    replay(session, [(day.name, u, obs) for u, obs in day_observations(h, day, at(0, 0).date(), rows=range(t + 1))])
    ngram = session.decide()
    last = (ngram.activity, ngram.choice.obj)
    assert last[0] == p.activity
    answers = cache / "llm-answers.sqlite3"
    db = sqlite3.connect(answers)
    keys = [r[0] for r in db.execute("SELECT key FROM answers")]
    db.close()
    assert keys
    for value in ('"abc"', "[]", "{}", "NaN", '{"answer": "x", "scores": {"x": NaN}}'):
        srv.kill()
        db = sqlite3.connect(answers)
        db.executemany("INSERT OR REPLACE INTO answers (key, value) VALUES (?, ?)", [(k, value) for k in keys])
        db.commit()
        db.close()
        srv.start()
        with srv.client() as c:
            p = c.prediction("A")
            assert p.llm_consulted and p.llm_fallback == "LLMCacheError", (value, p)
            assert (p.activity, p.object) == last
            assert c.stats("A")["llm_fallbacks"] == {"LLMCacheError": 1}


def test_a_cache_folder_that_is_a_file_does_not_stop_the_service(make_server, households, tmp_path):
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("x")
    srv = make_server({**ASK_ALWAYS, "GLOBE_LLM__CACHE_DIR": str(blocker)})
    with srv.client() as c:
        upload(c, "A", households["A"])
        _, p, _ = observe_until_consulted(c, households["A"])
        assert p.llm_fallback in ("LLMCacheError", "LLMUnavailableError")
        assert httpx.get(srv.url + "/health").json()["status"] == "ok"
