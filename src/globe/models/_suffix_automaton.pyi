from typing import Any

def extend(ids: dict[str, int], names: list[str], link: Any, length: Any, own: Any, label1: Any, target1: Any,
           start: Any, labels: Any, targets: Any, last: int, sequences: list[tuple[str, ...]]
           ) -> tuple[tuple[bytes, bytes, bytes, bytes, bytes, bytes, bytes, bytes], int]: ...
