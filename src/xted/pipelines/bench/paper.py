"""The paper's cells, for setting the bench's own beside them: its Table 1 (IQL on 20k target
and 20k source transitions: Src, Tgt, Tgt+Src, Tgt+Src (Edited)), Table 2 (DARA and DARA +
xTED) and its appendix's multi-source table (the three sources at once, unedited and edited),
mean and std over its 5 seeds, as printed. Table 1's cells sum to its printed totals;
Table 2's sum to 732.0 and 823.2, where it prints 734.2 and 824.2 (``PRINTED_TOTALS``)."""

from __future__ import annotations

from xted.pipelines.bench.columns import (
    SRC,
    TGT,
    TGT_ALL_EDITED,
    TGT_ALL_SRC,
    TGT_EDITED,
    TGT_EDITED_DARA,
    TGT_SRC,
    TGT_SRC_DARA,
)

PAPER_ALGO = "iql"  # both tables are IQL's (Table 2: DARA's reward correction on an IQL learner)
PAPER_COLUMNS = (SRC, TGT, TGT_SRC, TGT_EDITED, TGT_SRC_DARA, TGT_EDITED_DARA)

PRINTED_TOTALS = {SRC: 165.3, TGT: 716.1, TGT_SRC: 727.3, TGT_EDITED: 833.2, TGT_SRC_DARA: 734.2,
                  TGT_EDITED_DARA: 824.2}

# (env, target, gap): one (mean, std) per PAPER_COLUMNS entry.
_TABLES: dict[tuple[str, str, str], tuple[tuple[float, float], ...]] = {
    ("halfcheetah", "medium", "gravity"): ((8.4, 6.3), (39.5, 2.4), (41.1, 1.3), (40.6, 2.0), (40.6, 1.9), (41.1, 2.0)),
    ("halfcheetah", "medium", "friction"): ((14.4, 3.6), (39.5, 2.4), (27.9, 7.2), (41.2, 1.6), (30.8, 6.3), (41.4, 1.5)),
    ("halfcheetah", "medium", "thigh"): ((-0.1, 1.0), (39.5, 2.4), (40.3, 2.2), (40.7, 2.4), (40.4, 2.4), (41.5, 1.6)),
    ("halfcheetah", "medium-replay", "gravity"): ((8.4, 6.3), (26.2, 3.5), (29.5, 2.9), (31.3, 2.9), (29.9, 3.0),
                                                  (31.1, 3.1)),
    ("halfcheetah", "medium-replay", "friction"): ((14.4, 3.6), (26.2, 3.5), (23.2, 4.0), (31.8, 3.1), (22.8, 3.7),
                                                   (32.3, 3.1)),
    ("halfcheetah", "medium-replay", "thigh"): ((-0.1, 1.0), (26.2, 3.5), (29.0, 3.7), (33.0, 3.0), (29.3, 3.3),
                                                (32.8, 3.1)),
    ("halfcheetah", "medium-expert", "gravity"): ((8.4, 6.3), (40.1, 2.9), (40.4, 3.4), (43.8, 3.6), (41.5, 3.5),
                                                  (44.2, 3.3)),
    ("halfcheetah", "medium-expert", "friction"): ((14.4, 3.6), (40.1, 2.9), (27.1, 5.4), (43.2, 3.0), (29.8, 4.3),
                                                   (43.0, 3.5)),
    ("halfcheetah", "medium-expert", "thigh"): ((-0.1, 1.0), (40.1, 2.9), (37.4, 5.5), (43.0, 3.0), (37.9, 5.2),
                                                (43.3, 3.4)),
    ("walker2d", "medium", "gravity"): ((16.6, 6.2), (45.3, 15.9), (60.4, 9.5), (58.2, 11.7), (59.4, 10.2), (58.7, 11.0)),
    ("walker2d", "medium", "friction"): ((8.2, 1.4), (45.3, 15.9), (47.0, 12.8), (54.5, 13.7), (46.3, 11.5),
                                         (53.2, 14.3)),
    ("walker2d", "medium", "thigh"): ((7.6, 3.5), (45.3, 15.9), (49.6, 12.2), (58.9, 11.7), (48.5, 11.6), (56.8, 12.9)),
    ("walker2d", "medium-replay", "gravity"): ((16.6, 6.2), (16.6, 5.9), (19.5, 10.7), (23.3, 9.1), (20.3, 9.6),
                                               (22.5, 8.9)),
    ("walker2d", "medium-replay", "friction"): ((8.2, 1.4), (16.6, 5.9), (17.4, 6.2), (25.9, 9.1), (17.9, 5.7),
                                                (24.7, 8.5)),
    ("walker2d", "medium-replay", "thigh"): ((7.6, 3.5), (16.6, 5.9), (18.0, 6.7), (25.9, 9.1), (18.2, 6.1),
                                             (24.8, 9.0)),
    ("walker2d", "medium-expert", "gravity"): ((16.6, 6.2), (71.0, 21.0), (67.4, 11.1), (82.9, 18.1), (68.9, 12.4),
                                               (79.8, 16.6)),
    ("walker2d", "medium-expert", "friction"): ((8.2, 1.4), (71.0, 21.0), (75.1, 18.3), (74.0, 24.5), (74.2, 18.1),
                                                (73.4, 23.2)),
    ("walker2d", "medium-expert", "thigh"): ((7.6, 3.5), (71.0, 21.0), (77.0, 19.3), (81.0, 21.4), (75.3, 17.3),
                                             (78.6, 19.4)),
}


# The appendix's multi-source table, (env, target): Tgt+Src and Tgt+Src(Edited) with all three gaps'
# sources (printed totals 235.3 and 271.7; its Tgt column is Table 1's).
_MULTI_SOURCE: dict[tuple[str, str], tuple[tuple[float, float], tuple[float, float]]] = {
    ("halfcheetah", "medium"): ((37.6, 3.1), (39.7, 1.9)),
    ("halfcheetah", "medium-replay"): ((26.6, 3.5), (28.2, 3.2)),
    ("halfcheetah", "medium-expert"): ((35.3, 5.0), (41.3, 1.8)),
    ("walker2d", "medium"): ((41.8, 19.1), (58.5, 9.3)),
    ("walker2d", "medium-replay"): ((19.8, 6.2), (22.7, 7.6)),
    ("walker2d", "medium-expert"): ((74.2, 15.2), (81.3, 18.0)),
}


def paper_cell(env: str, target: str, gap: str | None, column: str, algo: str) -> dict | None:
    """The paper's ``{"mean", "std"}`` for this row, or None where it printed none (another algo,
    column or task)."""
    if algo != PAPER_ALGO:
        return None
    if column in (TGT_ALL_SRC, TGT_ALL_EDITED):
        cells = _MULTI_SOURCE.get((env, target)) if gap is None else None
        return None if cells is None else dict(zip(("mean", "std"), cells[column == TGT_ALL_EDITED]))
    cells = _TABLES.get((env, target, gap))
    if cells is None or column not in PAPER_COLUMNS:
        return None
    mean, std = cells[PAPER_COLUMNS.index(column)]
    return {"mean": mean, "std": std}
