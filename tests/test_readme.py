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
