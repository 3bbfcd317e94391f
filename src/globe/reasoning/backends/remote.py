"""Remote backend: any OpenAI-compatible chat endpoint via the official ``openai`` SDK.

Settings resolve as argument > environment (``OPENAI_BASE_URL``, ``OPENAI_API_KEY``) >
default. A short timeout and bounded retries keep one stuck request from stalling a run.
"""

from __future__ import annotations

import os

from globe.errors import (
    LLMAnswerError,
    LLMTimeoutError,
    LLMUnavailableError,
    MissingExtraError,
)
from globe.reasoning.backends.base import Choice, LLMBackend
from globe.reasoning.cache import AnswerCache, cache_key
from globe.reasoning.context import ChoiceContext, normalise_answer
from globe.reasoning.prompts import remote_prompt

SYSTEM = "You help a household robot anticipate which object a person needs next. Answer with one object name only."


def match_candidate(reply: str, candidates: tuple[str, ...]) -> str | None:
    """The candidate a reply names, after normalising case, spaces and underscores."""
    norm = normalise_answer(reply)
    by_norm = {normalise_answer(c): c for c in candidates}
    if norm in by_norm:
        return by_norm[norm]
    first_line = normalise_answer(reply.splitlines()[0]) if reply.strip() else ""
    return by_norm.get(first_line)


class RemoteBackend(LLMBackend):
    name = "remote"

    def __init__(self, *, model: str = "gpt-4.1", base_url: str | None = None, api_key: str | None = None,
                 temperature: float = 0.5, max_tokens: int = 10, timeout_s: float = 30.0,
                 max_retries: int = 2, cache: AnswerCache | None = None) -> None:
        self.model_name = model
        self.base_url = base_url
        self.api_key = api_key
        self.temperature = temperature
        self.max_tokens = max_tokens
        self.timeout_s = timeout_s
        self.max_retries = max_retries
        self.cache = cache
        self._client = None

    def _sdk(self):
        if self._client is None:
            try:
                import openai
            except ImportError as err:
                raise MissingExtraError("openai", "llm") from err
            base_url = self.base_url or os.environ.get("OPENAI_BASE_URL")
            api_key = self.api_key or os.environ.get("OPENAI_API_KEY")
            if not api_key:
                if base_url is None:
                    raise LLMUnavailableError("no API key: pass api_key or set OPENAI_API_KEY "
                                              "(or OPENAI_BASE_URL for a local server)")
                api_key = "not-needed"  # local OpenAI-compatible servers ignore it
            self._client = openai.OpenAI(base_url=base_url, api_key=api_key, timeout=self.timeout_s,
                                         max_retries=self.max_retries)
        return self._client

    def choose(self, context: ChoiceContext, candidates: tuple[str, ...]) -> Choice:
        prompt = remote_prompt(context, candidates)
        key = None
        if self.cache is not None:
            key = cache_key(backend=self.name, model=self.model_name, base_url=self.base_url, prompt=prompt,
                            temperature=self.temperature, max_tokens=self.max_tokens)
            hit = self.cache.get(key, valid=lambda v: isinstance(v, str))
            if hit is not None:
                return self._validated(hit, candidates, cached=True)
        import openai

        client = self._sdk()
        try:
            response = client.chat.completions.create(
                model=self.model_name,
                messages=[{"role": "system", "content": SYSTEM}, {"role": "user", "content": prompt}],
                temperature=self.temperature, max_tokens=self.max_tokens,
            )
        except openai.APITimeoutError as err:
            raise LLMTimeoutError(f"no answer within {self.timeout_s} s") from err
        except openai.APIError as err:
            raise LLMUnavailableError(f"remote LLM error: {err}") from err
        reply = (response.choices[0].message.content or "") if response.choices else ""
        if key is not None and self.cache is not None:
            self.cache.put(key, reply)
        return self._validated(reply, candidates)

    @staticmethod
    def _validated(reply: str, candidates: tuple[str, ...], cached: bool = False) -> Choice:
        if not reply.strip():
            raise LLMAnswerError("empty answer", raw=reply)
        answer = match_candidate(reply, candidates)
        if answer is None:
            raise LLMAnswerError(f"answer {reply!r} is not one of the candidates", raw=reply)
        return Choice(answer, None, raw=reply, cached=cached)
