"""Uncertainty-guided LLM reasoning: the gate, prompts, the answer cache and the backends."""
