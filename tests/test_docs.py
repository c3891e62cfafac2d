"""The documentation site and everything a user reads: the site builds strictly, nothing cites a
file outside the repository, every cited Physics section / quirk / test exists, every relative link
resolves, and every config key is documented."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS))

import gen_reference  # noqa: E402

# everything a user is shown: sources (messages, docstrings, schema descriptions, export comments),
# docs pages, README, shipped configs and sweeps
SCANNED = [ROOT / "README.md", *sorted((ROOT / "src").rglob("*.py")), *sorted(DOCS.rglob("*.md")),
           *sorted(DOCS.glob("*.py")), *sorted((ROOT / "configs").rglob("*.yaml")),
           *sorted((ROOT / "sweeps").rglob("*.yaml"))]

OUTSIDE = re.compile(r"shared/|spec/(?:config|outputs|physics|architecture|style)\.md|\.\./seeds|seeds/")
SECTION = re.compile(r"§\s*(\d+(?:\.\d+)?[a-z]?)|physics(?:\.md)?,? section (\d+(?:\.\d+)?[a-z]?)")
QUIRK = re.compile(r"quirks? #\s*(\d+)")
OLD_QUIRK = re.compile(r"quirks?\s*(?:\.md)?\s*§")
MD_NAME = re.compile(r"(?<![\w/.:-])((?:[\w.-]+/)*[\w-]+\.md)\b")
TEST_REF = re.compile(r"(tests/[\w/]+\.py)(?:::(\w+))?")
LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)")


def _lines(path: Path):
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        yield n, line


def _rel(path: Path) -> str:
    return str(path.relative_to(ROOT))


def _physics_sections() -> set[str]:
    heads = re.findall(r"^#{2,4} (\d+(?:\.\d+)?[a-z]?)\.? ", (DOCS / "physics.md").read_text(), re.M)
    return set(heads)


def _quirk_numbers() -> set[str]:
    text = (DOCS / "deviations.md").read_text()
    table = text.split("## Quirk by quirk", 1)[1].split("\n## ", 1)[0]
    return set(re.findall(r"^\| (\d+) \|", table, re.M))


def test_physics_page_keeps_the_numbered_sections_the_code_cites():
    """The section numbers are an interface: messages and docstrings cite them."""
    sections = _physics_sections()
    for s in ["1.2", "2.1", "3.2", "3.3", "4.1", "4.6", "4.7", "5.1", "6", "8.3b", "8.5", "8.6", "9", "11.2",
              "11.3", "12", "13", "14", "15"]:
        assert s in sections, f"Physics §{s} is gone from docs/physics.md"
    assert _quirk_numbers() == {str(n) for n in range(1, 27)}


def test_nothing_cites_a_file_outside_the_repository():
    bad = []
    for path in SCANNED:
        for n, line in _lines(path):
            if OUTSIDE.search(line) or OLD_QUIRK.search(line):
                bad.append(f"{_rel(path)}:{n}: {line.strip()[:120]}")
    assert not bad, "cites shared/ or the spec (cite the docs site instead: docs/physics.md §N, " \
                    "docs/deviations.md quirk #N, docs/reference/config.md):\n" + "\n".join(bad)


def test_every_cited_section_quirk_and_page_exists():
    sections, quirks = _physics_sections(), _quirk_numbers()
    md_files = [p for p in ROOT.rglob("*.md") if "site" not in p.relative_to(ROOT).parts[:1]]
    bad = []
    for path in SCANNED:
        for n, line in _lines(path):
            for m in SECTION.finditer(line):
                sec = m.group(1) or m.group(2)
                if sec not in sections:
                    bad.append(f"{_rel(path)}:{n}: §{sec} is not a section of docs/physics.md")
            for m in QUIRK.finditer(line):
                if m.group(1) not in quirks:
                    bad.append(f"{_rel(path)}:{n}: quirk #{m.group(1)} is not in docs/deviations.md")
            for m in MD_NAME.finditer(line):
                name = m.group(1)
                if "://" in line[max(0, m.start() - 80):m.start()]:
                    continue
                here = (path.parent / name).resolve()
                if here.exists() or (ROOT / name).exists() or (DOCS / name).exists():
                    continue
                tail = re.sub(r"^(?:\.\./|\./)+", "", name)  # a link written relative to another page
                if not any(str(p).endswith("/" + tail) for p in md_files):
                    bad.append(f"{_rel(path)}:{n}: {name} is not a file of the repository")
    assert not bad, "\n".join(bad)


def test_tests_named_in_the_docs_exist():
    """docs/deviations.md and the other pages pin behaviour by test name: the names must be real."""
    bad = []
    for path in [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]:
        for n, line in _lines(path):
            for m in TEST_REF.finditer(line):
                f, name = ROOT / m.group(1), m.group(2)
                if not f.exists():
                    bad.append(f"{_rel(path)}:{n}: {m.group(1)} does not exist")
                elif name and not re.search(rf"^\s*(?:async )?def {name}\(", f.read_text(), re.M):
                    bad.append(f"{_rel(path)}:{n}: {m.group(1)} has no test {name}")
            # `::name` continuing a previous tests/file.py in the same cell
            for m in re.finditer(r"`(tests/[\w/]+\.py)::\w+`(?:, `::(\w+)`)+", line):
                f = ROOT / m.group(1)
                for extra in re.findall(r"`::(\w+)`", m.group(0)):
                    if f.exists() and not re.search(rf"^\s*def {extra}\(", f.read_text(), re.M):
                        bad.append(f"{_rel(path)}:{n}: {m.group(1)} has no test {extra}")
    assert not bad, "\n".join(bad)


def test_relative_links_resolve():
    bad = []
    for path in [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]:
        for n, line in _lines(path):
            for m in LINK.finditer(line):
                target = m.group(1)
                if re.match(r"[a-z]+:", target) or target.startswith("#"):
                    continue
                file_part, _, anchor = target.partition("#")
                dest = (path.parent / file_part).resolve()
                if not dest.exists():
                    bad.append(f"{_rel(path)}:{n}: {target} does not resolve")
                elif not str(dest).startswith(str(ROOT)):
                    bad.append(f"{_rel(path)}:{n}: {target} leaves the repository")
                elif anchor.startswith("s") and dest == DOCS / "physics.md":
                    if anchor[1:].replace("-", ".") not in _physics_sections():
                        bad.append(f"{_rel(path)}:{n}: {target}: no such Physics section")
    assert not bad, "\n".join(bad)


def test_every_config_key_is_documented():
    missing, old = gen_reference.undocumented(), gen_reference.stale()
    assert not missing, ("config keys without a description (add Field(description=...) to the model, "
                         "or an entry to KEYS in docs/gen_reference.py): " + ", ".join(missing))
    assert not old, "docs/gen_reference.py KEYS describes keys that do not exist: " + ", ".join(old)


def test_generated_reference_shows_the_models_defaults_and_lammps_names():
    text = gen_reference.config_keys()
    minimize = text.split("### `minimize`", 1)[1].split("\n### ", 1)[0]
    row = next(line for line in minimize.splitlines() if line.startswith("| `maxiter` |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    from wallbatch.config.models import Config

    default = Config.model_fields["minimize"].annotation.__args__[0].model_fields["maxiter"].default
    assert cells[2] == f"`{default}`" and cells[4] == "`maxiter`" and "(> 0)" in cells[1]
    run = text.split("### `run`", 1)[1].split("\n### ", 1)[0]
    assert "| `steps` | integer (>= 0) | — |" in run and "| `thermo` | integer (>= 0) or mapping | `0` |" in run
    cli = gen_reference.cli_reference()
    assert "## `wallbatch run`" in cli and "| `--resume`, `--no-resume` | flag | `--no-resume` |" in cli


@pytest.mark.slow  # 3.5 s alone, 7-9 s on a busy 2-core machine
@pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocstrings") is None,
                    reason='mkdocs is not installed (pip install -e ".[docs]")')
def test_site_builds_strictly(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""),
               NO_MKDOCS_2_WARNING="1")
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    html = {p: p.read_text(encoding="utf-8") for p in (tmp_path / "site").rglob("*.html")}
    leaks = [f"{p.relative_to(tmp_path)}: {m.group(0)}" for p, t in html.items() for m in OUTSIDE.finditer(t)]
    assert not leaks, "the built site (docstrings included) cites files outside the repository:\n" + "\n".join(leaks)
    assert not any("<!-- generated:" in t for t in html.values())
    config = html[tmp_path / "site" / "reference" / "config" / "index.html"]
    from wallbatch.config.models import Config

    for key in Config.model_fields:
        assert f"<code>{key}</code>" in config, key


def _yaml_scenes() -> list[tuple[str, str]]:
    """Complete scenes shown in the docs (```yaml blocks with box:, atoms: and run:)."""
    out = []
    for path in sorted(DOCS.rglob("*.md")):
        for m in re.finditer(r"```yaml\n(.*?)```", path.read_text(encoding="utf-8"), re.S):
            text = m.group(1)
            if all(re.search(rf"^{k}:", text, re.M) for k in ("box", "atoms", "run")):
                out.append((f"{_rel(path)}:{path.read_text()[:m.start()].count(chr(10)) + 2}", text))
    return out


@pytest.mark.parametrize("where,text", _yaml_scenes(), ids=lambda v: v if isinstance(v, str) and ".md:" in v else "")
def test_scenes_shown_in_the_docs_are_valid(where, text, tmp_path):
    """A scene a page shows is accepted as it stands: validated, every case built."""
    import wallbatch

    path = tmp_path / "scene.yaml"
    path.write_text(text)
    report = wallbatch.check(path)
    assert report.ok and report.batches, (where, report.errors)


@pytest.mark.parametrize("where,text", _yaml_scenes(), ids=lambda v: v if isinstance(v, str) and ".md:" in v else "")
def test_scenes_shown_in_the_docs_run(where, text, tmp_path):
    """A scene a page shows also runs (40 steps): every case ok. A scene that passes `check` can
    still fail at its first step (random atoms inside a `side: out` region wall, say)."""
    import yaml

    import wallbatch

    scene = yaml.safe_load(text)
    scene["run"] = {"steps": 40, "thermo": 20}
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(scene, sort_keys=False))
    ds = wallbatch.run(path, progress=False)
    assert set(np.asarray(ds["status"]).ravel()) == {"ok"}, (where, np.asarray(ds["error"]).ravel())


def _yaml_sweeps() -> list[tuple[str, str]]:
    """Sweep files shown in the docs (```yaml blocks with base: and sweep:), as written in `sweeps/`."""
    out = []
    for path in [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]:
        for m in re.finditer(r"```yaml\n(.*?)```", path.read_text(encoding="utf-8"), re.S):
            text = m.group(1)
            if all(re.search(rf"^{k}:", text, re.M) for k in ("base", "sweep")):
                out.append((f"{_rel(path)}:{path.read_text()[:m.start()].count(chr(10)) + 2}", text))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("where,text", _yaml_sweeps(), ids=lambda v: v if isinstance(v, str) and ".md:" in v else "")
def test_sweeps_shown_in_the_docs_are_valid(where, text, tmp_path):
    """A sweep file a page shows (its base named from `sweeps/`, as the shipped ones are) is
    accepted as it stands: every case validated and built."""
    import wallbatch

    (tmp_path / "configs").symlink_to(ROOT / "configs")
    (tmp_path / "sweeps").mkdir()
    path = tmp_path / "sweeps" / "shown.yaml"
    path.write_text(text)
    report = wallbatch.check(path)
    assert report.ok and report.batches and not report.errors, (where, report.errors)


def test_the_docs_show_the_complete_example_and_the_quickstart():
    wheres = [w for w, _ in _yaml_scenes()]
    assert any(w.startswith("docs/reference/config.md") for w in wheres)
    assert any(w.startswith("docs/getting-started.md") for w in wheres)
    # the getting-started page shows configs/quickstart.yaml itself (without its comment lines)
    shown = next(t for w, t in _yaml_scenes() if w.startswith("docs/getting-started.md"))
    shipped = "".join(line for line in (ROOT / "configs" / "quickstart.yaml").read_text().splitlines(True)
                      if not line.startswith("#"))
    assert shown == shipped
