"""LLM backends: ``embedded`` (llama.cpp in process) and ``remote`` (OpenAI-compatible).

They are built from configuration by :func:`globe.assembly.llm_backend`.
"""

from globe.reasoning.backends.base import LLMBackend

__all__ = ["LLMBackend"]
