"""The bench's columns, each declared once: what it trains on, with which learner, and which
columns the report compares it with. Plain Python (the CLI lists them without loading JAX).

A column's ``data`` names data kinds, the target's first. A *data kind* says whether it is made per
gap (from that gap's source) or once per target, whether it reads a prior, and whether its making
wants an accelerator; :func:`xted.pipelines.bench.grid.plan` turns each into datasets or data cells.
A column's ``learner`` is None for the algorithm of the row itself, or a method that wraps that
algorithm's IQL backbone (DARA's reward correction, IGDF's and OTDF's source filters); such a column
exists for the IQL rows only. A new data-level method is one Column here (and, where it makes data
of a new kind, one DataKind).
"""

from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class DataKind:
    name: str
    per_target: bool = False  # made once per target, not per gap
    needs_prior: bool = False
    accelerator: bool = False  # its making runs a network (an edit, a generative model): a GPU helps
    help: str = ""


DATA_KINDS = {kind.name: kind for kind in (
    DataKind("target", per_target=True, help="the target dataset"),
    DataKind("source", help="the gap's source dataset"),
    DataKind("edit", needs_prior=True, accelerator=True, help="the source edited by the target's prior (the paper's edit)"),
    DataKind("guarded", needs_prior=True, accelerator=True, help="the source edited with the guard (xted's default edit)"),
    DataKind("oracle", help="the source relabelled by the target simulator"),
    DataKind("sources", per_target=True, help="every gap's source"),
    DataKind("edits", per_target=True, needs_prior=True, accelerator=True, help="every gap's source, edited"),
    DataKind("self-edit", per_target=True, needs_prior=True, accelerator=True,
             help="the target noised fully and denoised from its held first transitions"),
    DataKind("gen", per_target=True, needs_prior=True, accelerator=True, help="the prior's samples from pure noise"),
    DataKind("s4rl", per_target=True, help="the target with Gaussian state noise"),
    DataKind("ser", per_target=True, accelerator=True, help="samples of a transition diffusion model of the target"),
)}
LEARNER_WRAPPERS = ("dara", "igdf", "otdf")  # xted.rl.config.OFFLINE_ALGORITHMS' names of IQL wrappers
WRAPPED_ALGO = "iql"  # the algorithm every wrapper's backbone is


@dataclasses.dataclass(frozen=True)
class Column:
    name: str
    data: tuple[str, ...]  # data kinds, the target's first where it trains on the target
    family: str  # "table" (the paper's Tables 1 and 2), "guarded", "filter", "augment", "multi-source"
    learner: str | None = None  # one of LEARNER_WRAPPERS, or None: the row's algorithm
    compared_with: tuple[str, ...] = ()  # the report's P(this column > that one)
    env_settings: tuple[tuple[str, str], ...] = ()  # (env, "FIELD=VALUE") defaults of the learner wrapper

    @property
    def per_target(self) -> bool:
        """One cell per target (its own rows), not one per gap."""
        return self.data != ("target",) and all(DATA_KINDS[kind].per_target for kind in self.data)

    @property
    def needs_prior(self) -> bool:
        return any(DATA_KINDS[kind].needs_prior for kind in self.data)

    @property
    def reads_target(self) -> bool:
        return "target" in self.data

    @property
    def adds_to_target(self) -> bool:
        """Trains on the target and more: the table shows its gain against Tgt."""
        return self.reads_target and len(self.data) > 1

    def settings_for(self, env: str) -> list[str]:
        return [pair for scope, pair in self.env_settings if scope == env]


SRC, TGT, TGT_SRC, TGT_EDITED, TGT_ORACLE, TGT_SRC_DARA, TGT_EDITED_DARA = (
    "Src", "Tgt", "Tgt+Src", "Tgt+Edited", "Tgt+Oracle", "Tgt+Src DARA", "Tgt+Edited DARA")
TGT_GUARDED, TGT_GUARDED_DARA = "Tgt+Guarded", "Tgt+Guarded DARA"
TGT_SRC_IGDF, TGT_SRC_OTDF = "Tgt+Src IGDF", "Tgt+Src OTDF"
TGT_SELF_EDIT, TGT_GEN, TGT_S4RL, TGT_SER = "Tgt (Edit)", "Tgt (Gen)", "Tgt S4RL", "Tgt SER"
TGT_ALL_SRC, TGT_ALL_EDITED = "Tgt+All Src", "Tgt+All Edited"

COLUMNS: dict[str, Column] = {column.name: column for column in (
    # The paper's Tables 1 and 2 (DARA: its Table 2).
    Column(SRC, ("source",), "table"),
    Column(TGT, ("target",), "table"),
    Column(TGT_SRC, ("target", "source"), "table"),
    Column(TGT_EDITED, ("target", "edit"), "table", compared_with=(TGT, TGT_SRC)),
    Column(TGT_ORACLE, ("target", "oracle"), "table"),
    Column(TGT_SRC_DARA, ("target", "source"), "table", learner="dara", compared_with=(TGT_SRC,)),
    Column(TGT_EDITED_DARA, ("target", "edit"), "table", learner="dara", compared_with=(TGT_SRC_DARA,)),
    # The guarded edit (xted's default edit, beyond the paper), against every method.
    Column(TGT_GUARDED, ("target", "guarded"), "guarded",
           compared_with=(TGT, TGT_SRC, TGT_EDITED, TGT_SRC_DARA, TGT_SRC_IGDF, TGT_SRC_OTDF)),
    Column(TGT_GUARDED_DARA, ("target", "guarded"), "guarded", learner="dara", compared_with=(TGT_SRC_DARA,)),
    # Filtering the source by a learned dynamics score (IGDF; keep shares from the authors' README)
    # or by optimal transport to the target (OTDF).
    Column(TGT_SRC_IGDF, ("target", "source"), "filter", learner="igdf", compared_with=(TGT_SRC,),
           env_settings=(("halfcheetah", "keep_fraction=0.25"), ("walker2d", "keep_fraction=0.75"))),
    Column(TGT_SRC_OTDF, ("target", "source"), "filter", learner="otdf", compared_with=(TGT_SRC,)),
    # Single-domain augmentation (the paper's §5.4): the target plus as many transitions made from it.
    Column(TGT_SELF_EDIT, ("target", "self-edit"), "augment", compared_with=(TGT, TGT_S4RL, TGT_SER)),
    Column(TGT_GEN, ("target", "gen"), "augment", compared_with=(TGT,)),
    Column(TGT_S4RL, ("target", "s4rl"), "augment"),
    Column(TGT_SER, ("target", "ser"), "augment"),
    # Several sources at once (the paper's appendix "multi-source").
    Column(TGT_ALL_SRC, ("target", "sources"), "multi-source"),
    Column(TGT_ALL_EDITED, ("target", "edits"), "multi-source", compared_with=(TGT_ALL_SRC, TGT)),
)}


def family(name: str) -> tuple[str, ...]:
    return tuple(column.name for column in COLUMNS.values() if column.family == name)


TABLE_COLUMNS = family("table")
AUGMENT_COLUMNS = family("augment")
# The head-to-head of data-level methods: one protocol, one learner.
HEAD_TO_HEAD_COLUMNS = (TGT, TGT_SRC, TGT_SRC_DARA, TGT_SRC_IGDF, TGT_SRC_OTDF, TGT_EDITED, TGT_GUARDED)
# Names that stand for several columns in --columns.
COLUMN_SETS = {"table": TABLE_COLUMNS, "head-to-head": HEAD_TO_HEAD_COLUMNS, "augment": AUGMENT_COLUMNS,
               "multi-source": family("multi-source")}


def expand_column_sets(names: tuple[str, ...]) -> tuple[str, ...]:
    """``names`` with each set's name (``head-to-head``, ``table``, ...) replaced by its columns, each once."""
    return tuple(dict.fromkeys(column for name in names for column in COLUMN_SETS.get(name, (name,))))
