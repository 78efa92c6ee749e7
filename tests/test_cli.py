"""The `tfcontact` command's plan listing and its errors (fast: nothing is solved)."""

from tfcontact.cli import main


def test_plan_list_names_the_hopper(capsys):
    assert main(["plan", "--list"]) == 0
    out = capsys.readouterr().out
    assert "hopper" in out and "--task long" in out


def test_unknown_plan_and_task_are_named(capsys, tmp_path):
    assert main(["plan", "walker", "--out", str(tmp_path)]) == 2
    assert "unknown plan `walker`; available: hopper" in capsys.readouterr().err
    assert main(["plan", "hopper", "--task", "sprint", "--out", str(tmp_path)]) == 1
    assert "plan `hopper` has no task `sprint`; tasks: short, long" in capsys.readouterr().err


def test_bad_attempts_are_refused_before_solving(capsys, tmp_path):
    assert main(["plan", "hopper", "--attempts", "0", "--out", str(tmp_path), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "`attempts` must be a positive integer, got 0" in err
    assert not (tmp_path / "trajectory.npz").exists()
