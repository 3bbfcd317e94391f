"""Hypothesis strategies that damage CSV text the way people, spreadsheets and scripts do: bytes,
rows, cells and encodings. Each returns the new file content as bytes."""

from __future__ import annotations

import csv
import io

from hypothesis import strategies as st

ENCODINGS = ("utf-16", "utf-16-le", "latin-1", "cp1252", "utf-32")
# Cells that look almost right: the values a hand edit or an export produces.
TRICKY = st.sampled_from([
    "", " ", "-10", "+370", "3_90", "0x17", "1e3", "370.0", "３７０", "٣٧٠", "99999", "1441", "1440", "0", "00370",
    "nan",
    "\ufeff370", "370\u00a0", "\u200b", "cup#5", "plate#6", "kitchen#2", "home#1", "table#4", "counter#3", "Cup#5",
    "garage#9", "#", "a#", "#1", "sleeping", "idle", "[red]x[/red]", ":x:", "a,b", 'a"b', "a\nb", "a\x00b", "a\x07b",
    "x" * 300,
])


def cells_of(text: str) -> list[list[str]]:
    return [row for row in csv.reader(io.StringIO(text, newline=""))]


def text_of(rows: list[list[str]]) -> str:
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerows(rows)
    return out.getvalue()


@st.composite
def byte_damage(draw, data: bytes) -> bytes:
    """Insert, delete or overwrite a few bytes anywhere."""
    out = bytearray(data)
    for _ in range(draw(st.integers(1, 4))):
        pos = draw(st.integers(0, len(out)))
        op = draw(st.sampled_from(("insert", "delete", "replace")))
        special = st.sampled_from([b",", b"\n", b"\r", b'"', b"\xef\xbb\xbf", b"\x00"])
        blob = draw(st.binary(min_size=1, max_size=4) | special)
        if op == "insert":
            out[pos:pos] = blob
        elif op == "delete":
            del out[pos:pos + len(blob)]
        else:
            out[pos:pos + len(blob)] = blob
    return bytes(out)


@st.composite
def row_damage(draw, text: str) -> bytes:
    """Drop, duplicate, swap or truncate rows (the header included)."""
    rows = cells_of(text)
    for _ in range(draw(st.integers(1, 3))):
        if not rows:
            break
        i = draw(st.integers(0, len(rows) - 1))
        op = draw(st.sampled_from(("drop", "duplicate", "swap", "truncate", "extend")))
        if op == "drop":
            del rows[i]
        elif op == "duplicate":
            rows.insert(i, list(rows[i]))
        elif op == "swap":
            j = draw(st.integers(0, len(rows) - 1))
            rows[i], rows[j] = rows[j], rows[i]
        elif op == "truncate":
            rows[i] = rows[i][: draw(st.integers(0, max(0, len(rows[i]) - 1)))]
        else:
            rows[i] = rows[i] + [draw(TRICKY)]
    return text_of(rows).encode("utf-8")


@st.composite
def cell_damage(draw, text: str) -> bytes:
    """Replace a few cells (the header included) with tricky or arbitrary text."""
    rows = cells_of(text)
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, len(rows) - 1))
        if not rows[i]:
            continue
        j = draw(st.integers(0, len(rows[i]) - 1))
        rows[i][j] = draw(TRICKY | st.text(max_size=12))
    return text_of(rows).encode("utf-8")


@st.composite
def encoding_damage(draw, text: str) -> bytes:
    """The same text saved in another encoding, or with a non-ASCII character added first."""
    if draw(st.booleans()):
        rows = cells_of(text)
        i = draw(st.integers(1, max(1, len(rows) - 1))) if len(rows) > 1 else 0
        j = draw(st.integers(0, len(rows[i]) - 1))
        rows[i][j] = rows[i][j] + draw(st.sampled_from(["é", "ß", "€", "😀", "\u0301"]))
        text = text_of(rows)
    return text.encode(draw(st.sampled_from(ENCODINGS)), errors="replace")


_FULLWIDTH = str.maketrans("0123456789", "０１２３４５６７８９")
_ARABIC = str.maketrans("0123456789", "٠١٢٣٤٥٦٧٨٩")


def respellings(cell: str) -> list[str]:
    """Other spellings of the same value that a lenient parser would read as it: the silent
    changes a loader must refuse (or, for leading zeros, read as written)."""
    out = [cell.upper(), cell + "\u00a0", "\u200b" + cell, cell + "\x00", cell.replace("o", "о")]  # Cyrillic o
    if cell.isdigit():
        out += [f"+{cell}", f"{cell[0]}_{cell[1:]}" if len(cell) > 1 else f"{cell}_0", cell.translate(_FULLWIDTH),
                cell.translate(_ARABIC), f"{cell}.0", f"0{cell}", f"{cell}\n", f"{int(cell):#x}", f"{cell}e0"]
    return [o for o in out if o != cell]


@st.composite
def respelled(draw, text: str) -> bytes:
    """One cell (the header included) written another way that means the same to a lenient reader."""
    rows = cells_of(text)
    i = draw(st.integers(0, len(rows) - 1))
    j = draw(st.integers(0, len(rows[i]) - 1))
    options = respellings(rows[i][j])
    if options:
        rows[i][j] = draw(st.sampled_from(options))
    return text_of(rows).encode("utf-8")


def damaged(text: str) -> st.SearchStrategy[bytes]:
    data = text.encode("utf-8")
    return byte_damage(data) | row_damage(text) | cell_damage(text) | encoding_damage(text) | respelled(text)


@st.composite
def harmless(draw, text: str) -> bytes:
    """Changes the rules promise to accept with the same meaning: BOM, CRLF, quoting, spaces
    around cells, blank lines."""
    rows = cells_of(text)
    pad = draw(st.sampled_from(["", " ", "\t", "  "]))
    quote_all = draw(st.booleans())
    out = io.StringIO()
    writer = csv.writer(out, lineterminator=draw(st.sampled_from(["\n", "\r\n"])),
                        quoting=csv.QUOTE_ALL if quote_all else csv.QUOTE_MINIMAL)
    for row in rows:
        writer.writerow([c if quote_all else pad + c + pad for c in row])
        if draw(st.integers(0, 9)) == 0:
            out.write("\n")
    body = out.getvalue()
    return (b"\xef\xbb\xbf" if draw(st.booleans()) else b"") + body.encode("utf-8")
