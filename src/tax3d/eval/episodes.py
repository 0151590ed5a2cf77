"""An evaluation's finished episodes, kept as they finish in OUT/episodes/, so that a rerun of an interrupted
`tax3d eval` scores only the missing ones. Each file holds one episode's result beside the digest of the job that
made it (the episode's scene, goal source, weights, seed and policy settings): a file from any other job is not
reused. The folder is removed once the evaluation's results.json is written."""

from __future__ import annotations

import dataclasses
import hashlib
import io
import pickle
import shutil
from pathlib import Path

from tax3d.atomic import write_bytes
from tax3d.data.format import _PlainUnpickler
from tax3d.data.digest import feed

FOLDER = "episodes"
IGNORED = ("checkpoint", "device", "denoising")
"""job fields that change where or how an episode is computed, not its result (the weights' digest stands for the
checkpoint's path; the first episode's denoising steps are kept when its result carries them)"""


def job_digest(job, weights_sha256: str | None) -> str:
    h = hashlib.sha256((weights_sha256 or "").encode())
    feed(h, {f.name: getattr(job, f.name) for f in dataclasses.fields(job) if f.name not in IGNORED})
    return h.hexdigest()


class Episodes:
    """The kept episodes of one evaluation in OUT/episodes."""

    def __init__(self, out: Path, weights_sha256: str | None):
        self.folder, self.weights = Path(out) / FOLDER, weights_sha256

    def path(self, job) -> Path:
        return self.folder / f"{job.split}-{job.name}.pkl"

    def load(self, job) -> dict | None:
        """The kept result of this very job, or None (none kept, another job's, or unreadable)."""
        path = self.path(job)
        if not path.is_file():
            return None
        try:
            kept = _PlainUnpickler(io.BytesIO(path.read_bytes())).load()
        except Exception:  # a damaged file is scored again
            return None
        if not isinstance(kept, dict) or kept.get("job") != job_digest(job, self.weights):
            return None
        result = kept.get("result")
        return result if isinstance(result, dict) and (not job.denoising or result.get("denoising") is not None) \
            else None

    def keep(self, job, result: dict) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        write_bytes(self.path(job), pickle.dumps({"job": job_digest(job, self.weights), "result": result}))

    def remove(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)
