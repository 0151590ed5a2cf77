"""The learning-rate schedule of a training run, and the wall-clock plan of one given in minutes (--train.minutes):
the loop asks `Budget` for each step's learning rate and calls it at the timing step and at each validation.

The learning rate warms up linearly to lr, then decays along a cosine to 0 at the last step (App. B.2). A planned
run times its first steps (inside the warm-up, where the learning rate does not depend on the total) and one
validation, and fixes its steps and val_every to end on time. At every validation after that it is timed again:
steps that ran slower or faster shorten or lengthen it, the decay going on from its progress there (the knee), so
that the learning rate neither jumps nor rises. The plan's measurements and knee are saved in the training state;
train.steps and train.val_every in config.json hold what it planned. A resumed run is timed again too, from the
step it resumed at, so that its minutes in all (the earlier part's are saved) still end on time.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from typing import Callable

LONG_RUN_HOURS = 12  # a run planned longer than this is told so at its start

Agree = Callable[[tuple], tuple]
"""the values every process of a run takes (under torchrun, the mean over processes)"""


def cosine_lr(step: int, lr: float, warmup_steps: int, steps: int, knee: int = 0, knee_progress: float = 0.0) -> float:
    if step < warmup_steps:
        return lr * (step + 1) / warmup_steps
    progress = cosine_progress(step, warmup_steps, steps, knee, knee_progress)
    return lr * 0.5 * (1.0 + math.cos(math.pi * min(progress, 1.0)))


def cosine_progress(step: int, warmup_steps: int, steps: int, knee: int = 0, knee_progress: float = 0.0) -> float:
    """How far the decay is at `step`: 0 at the warm-up's end, 1 at `steps`; past a knee > 0, linearly from its
    progress there to 1 at `steps`."""
    if knee and step >= knee:
        return knee_progress + (1.0 - knee_progress) * (step - knee) / max(1, steps - knee)
    return (step - warmup_steps) / max(1, steps - warmup_steps)


def timing_step(warmup_steps: int) -> int:
    """The step after which a planned run fixes its steps (and any other run checks its length): in the warm-up."""
    return max(12, min(100, warmup_steps))


@dataclass
class Plan:
    """A run's schedule (lr, warmup_steps, steps) and, with minutes > 0, the plan that fixes steps and val_every."""

    lr: float
    warmup_steps: int
    steps: int
    val_every: int
    minutes: float = 0.0
    validations: int = 0
    """validate this many times, evenly over the planned steps (0: every val_every steps)"""
    step_seconds: float = 0.0
    """seconds per step, measured at the last timing"""
    val_seconds: float = 0.0
    """seconds per validation, measured at the last timing"""
    knee: int = 0
    """the step of the last re-plan (0: none)"""
    knee_progress: float = 0.0
    """the decay's progress at the knee"""
    since: tuple[int, float] | None = None
    """(step, time) from which this process measures the step rate; not saved"""
    made: bool = False
    """whether the plan is made and timed by this process (a resumed run's, from where it resumed)"""

    STATE = ("step_seconds", "val_seconds", "knee", "knee_progress")

    @classmethod
    def of(cls, train) -> "Plan":
        """The plan of a TrainConfig, as its options give it."""
        return cls(train.lr, train.warmup_steps, train.steps, train.val_every, train.minutes, train.validations)

    def state_dict(self) -> dict:
        return {name: getattr(self, name) for name in self.STATE}

    def load_state_dict(self, state: dict) -> None:
        for name in self.STATE:
            setattr(self, name, type(getattr(self, name))(state.get(name, getattr(self, name))))

    # -- the schedule ---------------------------------------------------------------------------------------------
    def lr_at(self, step: int) -> float:
        return cosine_lr(step, self.lr, self.warmup_steps, self.steps, self.knee, self.knee_progress)

    def progress(self, step: int) -> float:
        return cosine_progress(step, self.warmup_steps, self.steps, self.knee, self.knee_progress)

    # -- timing ---------------------------------------------------------------------------------------------------
    def start_step(self, step: int) -> None:
        """Before each step: the step rate is measured from the step before the timing step (after the first,
        slower steps) or from step 10."""
        at = timing_step(self.warmup_steps)
        if self.since is None and not self.made and min(10, at - 1) <= step < at:
            self.since = (step, time.time())

    def resume(self, step: int) -> None:
        """At the start of a resumed run: a plan made before is timed again from this step (at the next timing)."""
        if self.minutes > 0 and self.step_seconds > 0:
            self.made, self.since = True, (step, time.time())

    def timing(self, step: int) -> bool:
        """Whether this step ends the timing of the first steps (only in a run that started before it)."""
        return self.since is not None and not self.made and step == timing_step(self.warmup_steps)

    def rate(self, step: int, now: float | None = None) -> float:
        """Seconds per step since the measurement began."""
        return ((time.time() if now is None else now) - self.since[1]) / (step - self.since[0])

    def hours_left(self, step: int) -> float:
        """The hours the steps left take at the measured rate; the measurement ends (a run without minutes)."""
        hours = (self.steps - step) * self.rate(step) / 3600
        self.since = None
        return hours

    def make(self, step: int, started: float, time_validation: Callable[[], float],
             agree: Agree = lambda values: values) -> dict:
        """Fix steps and val_every to end `minutes` after `started` (a time), from the rate of the first steps and a
        validation timed by `time_validation` (its seconds); the record of the log line `plan`."""
        step_seconds = self.rate(step)
        val_seconds = time_validation()
        left = 60.0 * self.minutes - (time.time() - started) - val_seconds
        if self.validations > 0:
            steps = step + max(1, int((left - (self.validations - 1) * val_seconds) / step_seconds))
            val_every = max(1, -(-steps // self.validations))
        else:
            steps, val_every = step + self.steps_between_validations(left, step_seconds, val_seconds), self.val_every
        self.steps, self.val_every = agree((steps, val_every))
        self.step_seconds, self.val_seconds, self.made, self.since = step_seconds, val_seconds, True, (step, time.time())
        return {"steps": self.steps, "val_every": self.val_every, "minutes": self.minutes,
                "step_seconds": step_seconds, "val_seconds": val_seconds}

    def retime(self, step: int, started: float, val_started: float, agree: Agree = lambda values: values) -> dict | None:
        """At a validation (begun at `val_started`) of a plan made by this process: the steps that fit the minutes
        left at the rate since the plan or the validation before, the decay going on from where it is; the record
        of the log line `replan` when the steps change, else None."""
        if not (self.made and self.since[0] < step < self.steps):
            return None
        step_seconds = (val_started - self.since[1]) / (step - self.since[0])
        val_seconds = time.time() - val_started
        left = 60.0 * self.minutes - (time.time() - started) - val_seconds
        (steps,) = agree((step + self.steps_between_validations(left, step_seconds, val_seconds),))
        self.since, self.step_seconds, self.val_seconds = (step, time.time()), step_seconds, val_seconds
        if steps == self.steps:
            return None
        record = {"steps": steps, "planned": self.steps, "step_seconds": step_seconds, "val_seconds": val_seconds}
        self.knee_progress, self.knee, self.steps = self.progress(step), step, steps
        return record

    def steps_between_validations(self, seconds: float, step_seconds: float, val_seconds: float) -> int:
        """The steps (at least one) that fit `seconds` with a validation every val_every steps."""
        return max(1, int(seconds / (step_seconds + val_seconds / self.val_every)))


class Budget:
    """The loop's side of a Plan: the learning rate of each step, and the hooks that make the --train.minutes plan
    at the timing step and time it again at each validation, handing each new plan to `planned(message)`."""

    def __init__(self, plan: Plan, time_validation: Callable[[], float], agree: Agree,
                 planned: Callable[[str], None], main: bool = True):
        self.plan, self.time_validation, self.agree, self.planned, self.main = plan, time_validation, agree, planned, main

    def start(self, step: int) -> None:
        """Before the first step (of a resumed run too): a planned run lasts at least until its first steps are
        timed."""
        self.plan.resume(step)
        if self.plan.minutes > 0 and step < timing_step(self.plan.warmup_steps):
            self.plan.steps = max(self.plan.steps, timing_step(self.plan.warmup_steps))

    def lr(self, step: int) -> float:
        self.plan.start_step(step)
        return self.plan.lr_at(step)

    def timed(self, step: int, started: float) -> dict:
        """After each step: at the timing step, the plan (the log line's `plan`), or, without minutes, a note when
        the run would take long."""
        if not self.plan.timing(step):
            return {}
        if self.plan.minutes == 0:
            hours = self.plan.hours_left(step)
            if self.main and hours > LONG_RUN_HOURS:
                print(f"note: {self.plan.steps} steps at this machine's rate take about {hours:.0f} hours; "
                      f"--train.minutes M plans a run that ends after M minutes", file=sys.stderr)
            return {}
        record = self.plan.make(step, started, self.time_validation, self.agree)
        self.planned(f"planned {self.plan.steps} steps for {self.plan.minutes:g} minutes ({self.plan.step_seconds:.3f}"
                     f" s per step, {self.plan.val_seconds:.1f} s per validation)")
        return {"plan": record}

    def validated(self, step: int, started: float, val_started: float) -> dict:
        """After a validation begun at `val_started`: the re-plan (the log line's `replan`) where the steps change."""
        replan = self.plan.retime(step, started, val_started, self.agree)
        if replan is None:
            return {}
        self.planned(f"re-planned {self.plan.steps} steps for {self.plan.minutes:g} minutes "
                     f"({self.plan.step_seconds:.3f} s per step since the last timing)")
        return {"replan": replan}
