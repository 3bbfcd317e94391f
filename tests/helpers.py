"""Small helpers shared by tests."""

import socket


def free_port() -> int:
    """A TCP port on loopback that nothing listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def enumerate_paths(model, history, steps: int) -> list[tuple[float, tuple[str, ...]]]:
    """Every continuation of ``history`` by ``steps`` activities that ``model.predict_proba``
    allows, with its probability: the exact answer a beam without pruning must give."""
    out: list[tuple[float, tuple[str, ...]]] = [(1.0, ())]
    for _ in range(steps):
        grown = []
        for p, path in out:
            for a, q in model.predict_proba(tuple(history) + path).items():
                if q > 0:
                    grown.append((p * q, path + (a,)))
        out = grown
    return out
