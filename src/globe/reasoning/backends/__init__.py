"""LLM backends: ``embedded`` (llama.cpp in process) and ``remote`` (OpenAI-compatible)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from globe.reasoning.backends.base import LLMBackend

if TYPE_CHECKING:
    from globe.config import LLMConfig


def backend_from_config(cfg: "LLMConfig") -> LLMBackend | None:
    """Build the configured backend (``none`` -> None); heavy imports happen only here."""
    from globe.reasoning.cache import AnswerCache

    cache = AnswerCache(cfg.cache_dir / "llm-answers.sqlite3") if cfg.cache_dir else None
    if cfg.backend == "none":
        return None
    if cfg.backend == "embedded":
        from globe.reasoning.backends.embedded import EmbeddedBackend

        return EmbeddedBackend(model_path=cfg.model_path, n_threads=cfg.n_threads, n_ctx=cfg.n_ctx, cache=cache)
    from globe.reasoning.backends.remote import RemoteBackend

    return RemoteBackend(
        model=cfg.remote_model, base_url=cfg.base_url, temperature=cfg.temperature,
        max_tokens=cfg.max_tokens, timeout_s=cfg.timeout_s, max_retries=cfg.max_retries, cache=cache,
    )


__all__ = ["LLMBackend", "backend_from_config"]
