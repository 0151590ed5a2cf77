"""tax3d benchmark end to end at a tiny budget: train two steps, evaluate one episode per split, rerun resumes."""

import shutil

from tax3d.benchmark import Args, run


def test_benchmark_runs_and_resumes(generated, tmp_path, capsys):
    demos, _ = generated
    data = tmp_path / "data"
    for split in ("train", "unseen", "ood"):
        (data / split).mkdir(parents=True)
        shutil.copy(demos / "demo_0.npz", data / split / "demo_0.npz")
    args = Args(task="hangproccloth-simple", variants="cd", out=tmp_path / "bench", steps=2, episodes=1, workers=1,
                data=data)
    assert run(args) == 0
    out = capsys.readouterr().out
    assert "Success rate" in out and (tmp_path / "bench" / "results.md").exists()
    assert (tmp_path / "bench" / "cd" / "eval" / "report.html").exists()
    assert run(args) == 0  # everything is there already: nothing is trained or evaluated again
    again = capsys.readouterr().out
    assert "[benchmark] training" not in again and "[benchmark] evaluating" not in again
