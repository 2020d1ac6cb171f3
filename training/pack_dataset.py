"""Pack a data set folder compactly for the repository: the same records, sorted by index, in
parts of ROWS records with zstd compression, and the same manifest.

    python training/pack_dataset.py data/plate-n4-truth datasets/plate-n4-truth [--rows 10000]

The packed folder is a data set like any other: `prbdm dataset info` reads it, and copying it
back (`cp -r datasets/plate-n4-truth data/`) and re-running the generating command (its
`command` in docs/dataset.md) resumes the labelling where it stopped, every beam exactly once.
"""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

import _cli
from _cli import Setting

PROG = "pack_dataset"
SETTINGS = {"src": Setting("", "data set folder to pack"),
            "dst": Setting("", "packed folder to write (replaced when it exists)"),
            "rows": Setting(10000, "records per part")}


def main(argv=None) -> int:
    a = _cli.parse(PROG, __doc__.split("\n\n")[0], SETTINGS, argv, positional=("src", "dst"),
                   config=False)
    src, dst = Path(a["src"]), Path(a["dst"])
    if a["rows"] < 1:
        _cli.fail(PROG, f"--rows: must be an integer >= 1, got {a['rows']}")
    parts = sorted(src.glob("part-*.parquet"))
    if not (src / "_manifest.json").is_file() or not parts:
        _cli.fail(PROG, f"{src} is not a data set folder (no _manifest.json or parts)")
    if dst.resolve() == src.resolve():
        _cli.fail(PROG, f"dst: must differ from src ({src}); packing replaces dst")
    import pyarrow as pa  # after the arguments: --help works without the [data] extra
    import pyarrow.parquet as pq

    tables = [pq.read_table(p) for p in parts]
    meta = tables[0].schema.metadata
    table = pa.concat_tables(tables).sort_by("index")
    tmp = dst.with_name(dst.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    for i, start in enumerate(range(0, table.num_rows, a["rows"])):
        piece = table.slice(start, a["rows"]).replace_schema_metadata(meta)
        pq.write_table(piece, tmp / f"part-{i:06d}.parquet", compression="zstd",
                       compression_level=9)
    shutil.copy(src / "_manifest.json", tmp / "_manifest.json")
    shutil.rmtree(dst, ignore_errors=True)
    tmp.rename(dst)
    print(f"{table.num_rows} records in {i + 1} parts -> {dst} "
          f"({sum(p.stat().st_size for p in dst.iterdir()) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
