"""The documentation's examples run, and the configuration stays documented field by field.

Every fenced ```python block of a page in ``DOCUMENTED`` is executed, the blocks of one page in order in
one namespace (a later block may use what an earlier one defined); their ``assert`` statements check
the numbers the text quotes. Illustrative snippets that are not meant to run use another fence
(```text). Each field of every configuration class in ``tracker/config.py`` carries a one-line ``#:``
comment right above it (meaning, unit, default), and ``docs/tracker.md`` names every class.
"""

from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path

import pytest

import tracker.config as config_module

ROOT = Path(__file__).resolve().parents[1]
#: Every page with ```python examples: the README's tour and the user guide.
DOCUMENTED = ("README.md", "docs/tracker.md", "docs/road.md", "docs/scenarios.md", "docs/sensors.md", "docs/metrics.md",
              "docs/environment.md", "docs/studies.md", "docs/cli.md", "docs/maps.md")
FENCE = re.compile(r"^```python\n(.*?)^```", re.MULTILINE | re.DOTALL)


def python_blocks(page: str) -> list[str]:
    """The fenced ```python blocks of the page ``page`` (a path relative to the repository)."""
    return FENCE.findall((ROOT / page).read_text(encoding="utf-8"))


@pytest.mark.parametrize("page", DOCUMENTED)
def test_page_has_examples(page: str) -> None:
    assert python_blocks(page), f"{page} has no ```python example"


@pytest.mark.parametrize("page", DOCUMENTED)
def test_python_blocks_run(page: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)  # the examples' paths are relative to the repository
    namespace: dict[str, object] = {"__name__": f"docs_example_{Path(page).stem}"}
    for number, block in enumerate(python_blocks(page), start=1):
        code = compile(block, f"{page} (python block {number})", "exec")
        exec(code, namespace)  # noqa: S102 - the documentation's own examples


def _config_classes() -> list[type]:
    return [obj for obj in vars(config_module).values()
            if isinstance(obj, type) and dataclasses.is_dataclass(obj) and obj.__module__ == config_module.__name__]


def test_every_config_field_has_a_one_line_comment() -> None:
    path = ROOT / "tracker" / "config.py"
    lines = path.read_text(encoding="utf-8").splitlines()
    tree = ast.parse("\n".join(lines))
    missing = []
    for node in tree.body:
        if not isinstance(node, ast.ClassDef):
            continue
        for statement in node.body:
            if isinstance(statement, ast.AnnAssign) and isinstance(statement.target, ast.Name):
                above = lines[statement.lineno - 2].strip()  # the line right above the field
                if not above.startswith("#: ") or len(above) < 12:
                    missing.append(f"{node.name}.{statement.target.id}")
    assert not missing, f"fields without a '#:' comment right above them: {missing}"
    documented = {cls.__name__ for cls in _config_classes()}
    assert len(documented) >= 11 and "TrackerConfig" in documented


def test_tracker_page_names_every_config_class() -> None:
    text = (ROOT / "docs" / "tracker.md").read_text(encoding="utf-8")
    absent = [cls.__name__ for cls in _config_classes() if not re.search(rf"\b{cls.__name__}\b", text)]
    assert not absent, f"docs/tracker.md does not mention {absent}"
