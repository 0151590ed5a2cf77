"""The variants of the paper (Section 4 and its ablations): what each predicts, in which frame, from which inputs.

A plain registry without torch, so that checking a configuration does not load the model or the data code."""

from __future__ import annotations

from dataclasses import dataclass

from tax3d.errors import UsageError

VARIANTS = ("cd", "cp", "cd_w", "cp_w", "cd_nac", "cp_nac", "sd", "sp", "rd", "rp")


@dataclass(frozen=True)
class VariantSpec:
    """What a variant predicts, in which frame, and from which inputs (paper Section 4, ablations)."""

    name: str
    target: str  # "displacement" (cross-displacement) or "point" (goal action points)
    object_centric: bool = True  # action on its mean, anchor and goal on the anchor mean; False: world frame
    action_context: bool = True  # False: the model does not encode the action points (NAC)
    scene: bool = False  # one scene cloud (action + anchor) on its mean, self-attention only (SD/SP)
    diffusion: bool = True  # False: one regression pass with an MSE loss (RD/RP)


_SPECS = {
    "cd": VariantSpec("cd", "displacement"),
    "cp": VariantSpec("cp", "point"),
    "cd_w": VariantSpec("cd_w", "displacement", object_centric=False),
    "cp_w": VariantSpec("cp_w", "point", object_centric=False),
    "cd_nac": VariantSpec("cd_nac", "displacement", action_context=False),
    "cp_nac": VariantSpec("cp_nac", "point", action_context=False),
    "sd": VariantSpec("sd", "displacement", object_centric=False, scene=True),
    "sp": VariantSpec("sp", "point", object_centric=False, scene=True),
    "rd": VariantSpec("rd", "displacement", diffusion=False),
    "rp": VariantSpec("rp", "point", diffusion=False),
}


def variant_spec(name: str | VariantSpec) -> VariantSpec:
    """The spec of a variant name (case and '-' or '_' as in "CD-W" are accepted)."""
    if isinstance(name, VariantSpec):
        return name
    key = str(name).strip().lower().replace("-", "_")
    if key not in _SPECS:
        raise UsageError(f"unknown variant '{name}'; expected one of {', '.join(VARIANTS)}")
    return _SPECS[key]


# The rows of the paper's table (appendix D): the variants, the DP3 baseline, and two fixed goals that bound the
# policy, each the `tax3d eval --goal` it is scored with (no network, nothing trained).
BASELINE = "dp3"
FIXED_GOALS = {"floor": "mean", "ceiling": "demo"}
REGRESSION = ("rd", "rp")  # the paper runs them on the multimodal task alone
ROWS = (*VARIANTS, BASELINE, *FIXED_GOALS)
ROW_NAMES = {"cd": "TAX3D-CD", "cp": "TAX3D-CP", "floor": "mean goal of train (the floor)",
             "ceiling": "each demo's own goal (the ceiling)"}
# an evaluation's summary names what it scored by its variant, or by its --goal ("demo-goal", "mean-goal")
SCORED_NAMES = {BASELINE: "DP3", "demo-goal": "Each demo's own goal", "mean-goal": "The training set's mean goal"}


def table_rows(task: str) -> tuple[str, ...]:
    """The rows of the task's table in appendix D (RD and RP on multimodal only), then the floor and the ceiling."""
    return tuple(r for r in ROWS if r not in REGRESSION or task == "hangproccloth-multimodal")


def paper_key(row: str) -> str:
    """The row as the paper's table names it: "CD-W" for cd_w, "DP3"; the fixed goals as they are."""
    return row if row in FIXED_GOALS else row.upper().replace("_", "-")


def row_name(key: str) -> str:
    """A row of the table as a page names it, from its paper key: "TAX3D-CD", "CD-W", "mean goal of train (...)"."""
    row = key.lower().replace("-", "_")
    return ROW_NAMES.get(row, key)


def display_name(variant: str) -> str:
    """What an evaluation's summary scored, by its variant ("cd", "dp3", "demo-goal"): "TAX3D-CD", "DP3", ..."""
    return SCORED_NAMES.get(variant, f"TAX3D-{variant.upper()}")
