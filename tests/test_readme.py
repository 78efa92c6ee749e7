"""The README's example runs as written (its code is scripts/ball_drop.py)."""

import re
import runpy
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def test_readme_example_is_the_script():
    readme = (ROOT / "README.md").read_text()
    block = re.search(r"```python\n(.*?)```", readme, re.S).group(1)
    script = (ROOT / "scripts" / "ball_drop.py").read_text()
    assert block.strip() in script


def test_readme_commands_open_the_readme():
    first = (ROOT / "README.md").read_text().split("```")[1].strip().splitlines()
    assert first[1].startswith("python3.11 -m venv .venv") and "tfcontact plan hopper" in first[1]
    assert first[2] == ".venv/bin/python -m pytest"
    assert ".venv/bin/python -m pytest" in (ROOT / ".ci" / "run").read_text()


def test_ball_drop_example(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    namespace = runpy.run_path(str(ROOT / "scripts" / "ball_drop.py"))
    impacts = namespace["phys"].impact_times
    assert impacts.size == 1
    np.testing.assert_allclose(impacts[0], np.sqrt(2 * 1.0 / 9.81), atol=1e-6)
    assert (tmp_path / "ball_drop.png").stat().st_size > 0
    assert "impact at t =" in capsys.readouterr().out


def test_readme_api_example_is_the_script_and_runs(tmp_path, monkeypatch, capsys):
    """URDF to verified plan to replay through the top-level API (the second example)."""
    readme = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", readme, re.S)
    api = [b for b in blocks if "import tfcontact\n" in b]
    assert len(api) == 1 and api[0].strip() in (ROOT / "scripts" / "hopper_api.py").read_text()
    monkeypatch.chdir(tmp_path)
    namespace = runpy.run_path(str(ROOT / "scripts" / "hopper_api.py"))
    result = namespace["result"]
    assert result.success and result.verification.passed and result.task.passed
    assert {c.name for c in result.task.checks} == {"end x", "lift-offs contact 0", "motion"}
    assert (tmp_path / "hopper.html").stat().st_size > 10_000
    assert "converged True True" in capsys.readouterr().out


def test_top_level_names_resolve():
    import tfcontact

    for name in tfcontact.__all__:
        assert getattr(tfcontact, name) is not None, name
    assert tfcontact.plan.__module__ == "tfcontact.task.solve"  # problems and tasks
    try:
        tfcontact.no_such_thing  # noqa: B018
    except AttributeError as error:
        assert "no attribute 'no_such_thing'" in str(error)
    else:
        raise AssertionError("an unknown name resolved")
