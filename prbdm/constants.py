"""The numbers that several parts of prbdm share, in one place that imports nothing (no torch, no
scikit-fem), so that ``prbdm predict``, the data-set parent process and the command-line parsers
can use them without loading the physics.

Each constant is documented where its reasoning lives; this module only holds the value.
"""

#: bounds on each link-length fraction gamma_j (docs/conventions.md §3, Eq. 13)
GAMMA_MIN, GAMMA_MAX = 0.025, 0.975

#: what a fit or a network minimises (prbdm.objectives): the paper's eigenvalue loss (Eq. 12-13)
#: or the worst relative frequency error per pose
OBJECTIVES = ("eigenvalue", "frequency")

#: start points of a fit up to 4 joints (twice as many beyond; prbdm.fit.default_starts)
DEFAULT_STARTS = 64

#: refinement from a network's answer: its best candidate segmentations, and iterations
#: (prbdm.fit.refine_starts; measured in docs/validation.md)
REFINE_CANDIDATES = 4
REFINE_ITER = 15

#: a checkpoint whose own held-out test (its metadata's ``test``) is worse than this is announced
#: as a rough estimate whenever it answers (prbdm.surrogate.Surrogate.accuracy_warning): the PRBDM's
#: paper loss median [%] and the median error of any predicted truth frequency [%]. The shipped
#: beam networks are a decade inside both (docs/validation.md); a plate network may not be.
ACCURACY_WARN_LOSS_PERCENT = 2.0
ACCURACY_WARN_FREQ_PERCENT = 1.0

#: full widths over length that split a checkpoint's held-out test into bands (its metadata's
#: ``test.by_width``, written by training/train_surrogate.py): an answer quotes, and is judged by,
#: the accuracy measured on test panels of its own width, where the checkpoint has one. One
#: network can be within 1 % on panels 0.05-0.2 L wide and 10 % off on the paper's 0.4-1 L ones
#: (`mindlin-n4`, docs/validation.md); a single number would call both rough, or both fine. A band
#: is recorded only with at least ACCURACY_BAND_MIN_BEAMS test panels (the median of 100 skewed
#: losses is still uncertain by a tenth of their spread or so: a band just under a limit can be
#: chance, which the shipped checkpoints' bands are checked against held-out sets for).
ACCURACY_WIDTH_EDGES = (0.1, 0.2, 0.4)
ACCURACY_BAND_MIN_BEAMS = 100

#: `--truth auto` gives a panel to the plate network only when it is wider than this (full width
#: over length): below it the beam network was measured closer to the plate truth than the plate
#: network (`python benchmarks/plate_width_bands.py --data datasets/plate-n4-narrow-seed3
#: --checkpoints checkpoints/plate-n4.safetensors,checkpoints/beam-n4.safetensors`,
#: docs/validation.md); between 0.05 L and this the plate is the truth, the beam network the answer.
#: The Kirchhoff plate network's rule only: a Mindlin network was measured closer to the Mindlin
#: truth than the beam network down to 0.05 L (`--data datasets/mindlin-n4-narrow-seed3 --auto
#: mindlin`: 0.86 % against 3.8 % at 0.05-0.1 L)
PLATE_NETWORK_MIN_WIDTH = 0.1

#: every answer checks itself (prbdm.preflight.check_answer): the PRBDM's frequencies, at every
#: pose, against the truth it was made for (a network's own predicted truth; a fit's truth). A
#: mode further off than SELF_CHECK_TOLERANCE gets a warning naming the mode, the error and the
#: remedy; one further off than SELF_CHECK_IMPLAUSIBLE (relative frequency error) is not a model
#: of the panel: a network's answer is refused (prbdm predict exits 1, `--truth auto` asks the
#: next network), a fit's gets a warning saying so. Fits of the paper's wide panels reach a worst
#: mode of 24 % at p90 (docs/conventions.md, the bending spectrum), so 50 % is a failure, not a
#: hard panel.
SELF_CHECK_TOLERANCE = 0.05
SELF_CHECK_IMPLAUSIBLE = 0.5
#: ... and what an answer made with the paper's eigenvalue loss is judged by: that loss [%]
#: against the truth, over the poses. The loss weighs the highest mode most and lets mode 1 drift
#: 10-30 % at the deflected poses by design (docs/method.md), so a per-mode tolerance would warn
#: on every such answer; its fits reach 0.1 % (beam) and 1.1 % (plate) median on the paper's
#: panels (README), so beyond 2 % the answer is worse than its method makes it
SELF_CHECK_LOSS_PERCENT = 2.0
