"""Figures published in the GLOBE paper (HOMER+), shown beside ours, always labelled as such."""

from __future__ import annotations

# method -> (activity F1, object F1, mean F1), weighted F1 averaged over households A, B, C
TABLE1 = {
    "globe": (0.80, 0.65, 0.73),
    "ngram": (0.79, 0.64, 0.72),
    "slate_pro": (0.78, 0.69, 0.74),
    "llm_only": (0.57, 0.00, 0.29),
}
# method -> (training s, inference s) for the whole test split
TABLE2 = {"globe": (8.33, 192.0), "ngram": (8.33, 0.86)}
