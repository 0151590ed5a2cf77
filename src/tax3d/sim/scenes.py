"""The registry of scenes: a task's scene name -> its environment class, and one environment per worker process.

It imports both scene modules, so neither needs the other (HangBag builds on the cloth scene's environment)."""

from __future__ import annotations

from tax3d.sim.bag_env import HangBagEnv
from tax3d.sim.env import HangClothEnv

SCENES: dict[str, type[HangClothEnv]] = {"cloth": HangClothEnv, "bag": HangBagEnv}

_PROCESS_ENVS: dict[tuple[str, bool], HangClothEnv] = {}


def env_class(scene: str) -> type[HangClothEnv]:
    """The environment of a task's scene: "cloth" (HangProcCloth) or "bag" (HangBag)."""
    if scene not in SCENES:
        raise ValueError(f"unknown scene {scene!r}; expected one of {', '.join(SCENES)}")
    return SCENES[scene]


def process_env(floor: bool = True, scene: str = "cloth") -> HangClothEnv:
    """One scene per worker process, scene kind and floor setting, reused across episodes."""
    key = (scene, floor)
    if key not in _PROCESS_ENVS:
        _PROCESS_ENVS[key] = env_class(scene)(floor=floor)
    return _PROCESS_ENVS[key]
