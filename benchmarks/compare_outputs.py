"""Are two runs' data outputs the same? Compare the files under two results/ folders byte for byte,
masking only the code version that provenance records (``<version>+<12 hex>``: it changes with any
source change, including a refactor that changes no output), so that a change that should leave
every output alone can be shown to (docs/testing.md, "Outputs unchanged").

    python benchmarks/compare_outputs.py OLD/results NEW/results [--include-figures]

Compared: every file except logs, Snakemake's benchmark files, timing sidecars (wall times differ
on every run), Optuna's study databases (trial timestamps), the HTML report and Snakemake's graphs
(``.dot``, their edge order varies); PNG figures only with ``--include-figures``. A zip container
(a TorchScript export, ``.npz``) is compared member by member, without a TorchScript archive's
random save id and with each run's checkout path (the results folder's parent, which its debug
tables name) masked; a Parquet file by its data and masked metadata. Prints one line per differing
or missing file and a count per outcome; exits 1 when any file differs or is missing on one side.
"""

from __future__ import annotations

import argparse
import re
import sys
import zipfile
from collections import Counter
from pathlib import Path

CODE_VERSION = re.compile(rb"\d+\.\d+\.\d+\+[0-9a-f]{12}")
SKIP_DIRS = {"logs", "benchmarks"}
SKIP_SUFFIXES = {".sqlite", ".html", ".snakemake_timestamp", ".dot"}


def masked(data: bytes) -> bytes:
    """``data`` with every code version replaced by a placeholder of the same length."""
    return CODE_VERSION.sub(lambda m: b"v" * len(m.group(0)), data)


# A TorchScript archive's random save id, and its debug tables name the source files they were
# traced from by absolute path (the checkout's): neither is the model.
SAVE_ID = "/.data/serialization_id"


def _members(path: Path, root: Path) -> dict[str, bytes]:
    """A zip's members, masked, with the run's checkout path (``root``) replaced by a placeholder
    and a TorchScript archive's save id left out."""
    checkout = str(root.resolve()).encode()
    with zipfile.ZipFile(path) as z:
        return {
            i.filename: masked(z.read(i)).replace(checkout, b"<checkout>")
            for i in z.infolist()
            if not i.filename.endswith(SAVE_ID)
        }


def _parquet(path: Path) -> tuple[object, dict[bytes, bytes]]:
    """A Parquet file's data (schema without metadata) and its metadata, masked. The file also
    holds its Arrow schema base64-encoded (``ARROW:schema``), metadata included, where masking
    cannot reach: that copy is left out."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    meta = {k: masked(v) for k, v in (table.schema.metadata or {}).items() if k != b"ARROW:schema"}
    return table.replace_schema_metadata(None), meta


def same(a: Path, b: Path, roots: tuple[Path, Path] | None = None) -> tuple[bool, bool]:
    """(same after masking, same byte for byte); ``roots``: the two runs' checkouts."""
    da, db = a.read_bytes(), b.read_bytes()
    if da == db:
        return True, True
    if zipfile.is_zipfile(a) and zipfile.is_zipfile(b):
        ra, rb = roots or (a.parent, b.parent)
        return _members(a, ra) == _members(b, rb), False
    if masked(da) == masked(db):
        return True, False
    if a.suffix == ".parquet":
        import polars as pl

        (ta, ma), (tb, mb) = _parquet(a), _parquet(b)
        # polars compares NaN equal to NaN (pyarrow's Table.equals does not)
        same_data = ta.schema == tb.schema and pl.from_arrow(ta).equals(pl.from_arrow(tb))
        return same_data and ma == mb, False
    return False, False


def compared(root: Path, figures: bool) -> set[str]:
    out = set()
    for f in root.rglob("*"):
        rel = f.relative_to(root)
        if not f.is_file() or rel.parts[0] in SKIP_DIRS or f.suffix in SKIP_SUFFIXES:
            continue
        if f.name.endswith(".timing.json") or f.name == "timing.json":
            continue
        if f.suffix == ".png" and not figures:
            continue
        out.add(rel.as_posix())
    return out


def compare(old: Path, new: Path, figures: bool = False) -> tuple[Counter, list[str]]:
    """Outcome counts and one line per file that differs or exists on one side only."""
    a, b = compared(old, figures), compared(new, figures)
    counts: Counter = Counter()
    lines = []
    for rel in sorted(a | b):
        if rel not in b:
            counts["only in old"] += 1
            lines.append(f"only in {old}: {rel}")
        elif rel not in a:
            counts["only in new"] += 1
            lines.append(f"only in {new}: {rel}")
        else:
            equal, exact = same(old / rel, new / rel, (old.parent, new.parent))
            key = "differ" if not equal else "identical" if exact else "same but code version"
            counts[key] += 1
            if not equal:
                lines.append(f"differs: {rel}")
    return counts, lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old", type=Path, help="the first run's results/ folder")
    ap.add_argument("new", type=Path, help="the second run's results/ folder")
    ap.add_argument("--include-figures", action="store_true", help="compare PNG figures too")
    args = ap.parse_args(argv)
    for d in (args.old, args.new):
        if not d.is_dir():
            ap.error(f"{d} is not a folder")
    counts, lines = compare(args.old, args.new, args.include_figures)
    for line in lines:
        print(line)
    by_ext = Counter(Path(r).suffix or "(none)" for r in compared(args.new, args.include_figures))
    print("files compared by type: " + ", ".join(f"{k} {v}" for k, v in sorted(by_ext.items())))
    print("; ".join(f"{k}: {v}" for k, v in sorted(counts.items())))
    return 1 if counts["differ"] or counts["only in old"] or counts["only in new"] else 0


if __name__ == "__main__":
    sys.exit(main())
