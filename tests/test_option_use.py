"""lab.studies.option_use: which options of each command the kept command lines name."""

from lab.studies.option_use import count, options_of
from tax3d.cli.train import Args


def test_nested_sections_and_negated_flags_count_as_their_option():
    options = options_of(Args)
    assert "--train.seed" in options and "--data.rotate" in options and "--out" in options
    used = count(["tax3d train --train.seed 3 --data.no-rotate && tax3d eval --seed 2",
                  "python -m tax3d.cli train --train.seed=4 --model.variant cp", "tax3d table --num-train 64"])
    assert used["train"]["--train.seed"] == 2 and used["train"]["--data.rotate"] == 1
    assert used["train"]["--model.variant"] == 1 and used["train"]["--train.lr"] == 0
    assert used["eval"]["--seed"] == 1 and used["table"]["--num-train"] == 1
