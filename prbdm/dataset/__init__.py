"""Labelled data sets of random beams: generation, storage, resume, summary.

A data set is a folder::

    DIR/_manifest.json        the spec, seed, count, columns, package versions, git commit, runs
    DIR/part-000000.parquet   records, one per beam index, flat columns (lists for arrays)
    DIR/part-000001.parquet   ...

Read it without prbdm: ``pandas.read_parquet(DIR)`` or ``pyarrow.parquet.read_table(DIR)`` (they
skip names starting with ``_`` or ``.``, which is why the manifest is ``_manifest.json``).

The package, in the order a run uses it:

- :mod:`.schema` -- the **spec** (:func:`make_spec`): everything that decides a record, the
  random-beam generator and its seed (docs/conventions.md §1), the truth model and its mode count, the PRBDM
  (joints, modes, law, poses, starts) and the fit's objective. A later run on the same folder must
  ask for the same spec, or it is refused naming the first differing field. The count is not part
  of the spec: asking for more extends the set. Also the record **columns**.
- :mod:`.label` -- **labelling** in the workers: :func:`label_beam` ``(index, spec) -> record``,
  :func:`label_beams` for a chunk of beams fitted in one batch; a failure is an error record.
- :mod:`.storage` -- the **folder**: manifest, whole-or-nothing part files, the lock, provenance,
  :func:`info`.
- :mod:`.execute` -- **execution**: one loop over a ``concurrent.futures`` executor, be it this
  process, a local process pool or a Dask cluster (``Client.get_executor()``).
- :mod:`.run` -- :func:`generate`: lock, find the missing indices, label, write, **resume**.
"""
from __future__ import annotations

from .label import chunks, fit_seed, label_beam, label_beams, label_chunk
from .run import Progress, generate
from .schema import (
                     COLUMNS,
                     DEFAULT_FIT_BATCH,
                     DEFAULT_OBJECTIVE,
                     DEFAULT_STARTS,
                     FORMAT,
                     FORMAT_VERSION,
                     MANIFEST,
                     OBJECTIVES,
                     beam_for,
                     make_spec,
                     refused_by_truth,
                     spec_difference,
)
from .storage import (
                     FolderLock,
                     existing_indices,
                     git_commit,
                     info,
                     part_files,
                     read_manifest,
                     read_table,
                     versions,
)

# the names other modules of the project used before the package existed
_git_commit, _versions = git_commit, versions

__all__ = ["make_spec", "label_beam", "label_beams", "label_chunk", "generate", "info",
           "read_table", "read_manifest", "part_files", "beam_for", "refused_by_truth", "chunks",
           "spec_difference",
           "fit_seed", "existing_indices", "FolderLock", "Progress", "MANIFEST", "FORMAT",
           "FORMAT_VERSION", "COLUMNS", "OBJECTIVES", "DEFAULT_OBJECTIVE", "DEFAULT_FIT_BATCH",
           "DEFAULT_STARTS"]
