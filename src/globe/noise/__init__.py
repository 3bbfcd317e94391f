"""HOMER-Noise: plausible object movements by a person, a pet or a toddler, proposed by an LLM,
checked against the home's physics and simple per-type rules, inserted at a noise level."""
