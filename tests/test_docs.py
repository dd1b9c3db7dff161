"""The documentation site: the generated config and CLI reference pages, and ``mkdocs build --strict``
(broken links, missing anchors and missing references fail the build, and so this test)."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import yaml
from hydra.core.config_store import ConfigStore

from sphri.args import arg
from sphri.command import VERBS, Verb
from sphri.config import ComponentSchema, setting
from sphri.docs_gen import cli_reference, config_reference, range_words, setting_rows

ROOT = Path(__file__).resolve().parents[1]


@dataclasses.dataclass
class FakeSchema(ComponentSchema, group="fakegroup"):
    _target_: str = "mylab.FakeEncoder"
    width_mm: float = setting(12.5, lo=0, lo_open=True)
    """Width of a fake taxel (mm)."""


@dataclasses.dataclass
class FakeSchemaWithGap(FakeSchema):
    taxel_gap: int = setting(3, lo=1, hi=9, integer=True)
    """Taxels left between two sensing rows."""


def _fake_conf(tmp_path: Path, schema: type, name: str) -> Path:
    ConfigStore.instance().store(name=f"schema_fakegroup_{name}", node=schema)
    (tmp_path / "fakegroup").mkdir(parents=True, exist_ok=True)
    (tmp_path / "fakegroup" / f"{name}.yaml").write_text(
        f"# A fake component for the reference test. More words.\ndefaults:\n"
        f"  - /schema_fakegroup_{name}@_here_\n  - _self_\n\nwidth_mm: 8.0\n"
    )
    return tmp_path


def test_a_setting_added_to_a_schema_appears_in_the_config_reference(tmp_path):
    before = config_reference(groups=["fakegroup"], conf_dir=_fake_conf(tmp_path / "a", FakeSchema, "plain"))
    assert "### fakegroup=plain" in before and "A fake component for the reference test." in before
    assert "| `fakegroup.width_mm` | float | (0, inf) | `8.0` | Width of a fake taxel (mm). |" in before
    assert "taxel_gap" not in before

    after = config_reference(groups=["fakegroup"], conf_dir=_fake_conf(tmp_path / "b", FakeSchemaWithGap, "gap"))
    row = "| `fakegroup.taxel_gap` | int | integer in [1, 9] | `3` | Taxels left between two sensing rows. |"
    assert row in after
    assert "Class: `mylab.FakeEncoder`" in after


def test_setting_rows_read_type_range_default_and_meaning():
    rows = {r.name: r for r in setting_rows(FakeSchemaWithGap)}
    assert "_target_" not in rows
    assert (rows["taxel_gap"].type, rows["taxel_gap"].range, rows["taxel_gap"].default) == (
        "int",
        "integer in [1, 9]",
        "`3`",
    )
    assert rows["width_mm"].meaning == "Width of a fake taxel (mm)."


def test_range_words():
    from sphri.config import Range

    assert range_words(Range(1, 1000)) == "[1, 1000]"
    assert range_words(Range(0, None, lo_open=True)) == "(0, inf)"
    assert range_words(Range(choices=("a", "b"))) == "one of a, b"
    assert range_words(Range(1, None, integer=True, optional=True)) == "integer in [1, inf) or None"
    assert range_words(None) == ""


def test_the_real_config_reference_lists_the_packaged_components():
    page = config_reference(groups=["encoder", "layout", "noise"])
    assert "### encoder=ellipse" in page and "### noise=salt_pepper" in page
    assert "| `layout.res` |" in page
    assert "## Experiments" in page and "| `resolution_sweep` | The reference study's curve" in page


@dataclasses.dataclass
class FakeArgs:
    source: str = arg(positional=True, metavar="SOURCE", help="the folder to read")
    level: int = arg(2, help="how loud the fake verb is")


def fake_command(args: FakeArgs) -> int:
    """Read SOURCE and say nothing."""
    return 0


def test_a_verb_and_its_arguments_appear_in_the_cli_reference():
    fake = Verb(
        "fake-verb", "a fake verb for the reference test", "args", f"{__name__}:fake_command", f"{__name__}:FakeArgs"
    )
    page = cli_reference([*VERBS, fake])
    for v in VERBS:
        assert f"\n## {v.name}\n" in page, v.name
    assert "| [`fake-verb`](#fake-verb) | a fake verb for the reference test |" in page
    assert "Read SOURCE and say nothing." in page
    assert "| `level=` | INT | `2` | how loud the fake verb is |" in page
    assert "| `SOURCE` | SOURCE | (required) | the folder to read |" in page


def _mkdocs(config: Path, site: Path) -> subprocess.CompletedProcess:
    env = {
        **os.environ,
        "NO_MKDOCS_2_WARNING": "1",
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    }
    return subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(config), "-d", str(site)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_the_docs_site_builds_strictly(tmp_path):
    """``mkdocs build --strict`` (never ``--quiet``: it hides the warnings strict mode counts): every nav page exists, every link and anchor resolves, the API pages'
    references are found; the generated reference pages are in the site."""
    done = _mkdocs(ROOT / "mkdocs.yml", tmp_path / "site")
    assert done.returncode == 0, done.stdout + done.stderr
    config_page = (tmp_path / "site" / "reference" / "config" / "index.html").read_text()
    assert "layout.res" in config_page
    assert "check-data" in (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    assert "make_pipeline" in (tmp_path / "site" / "reference" / "api" / "index.html").read_text()


def test_a_broken_link_fails_the_strict_build(tmp_path):
    """The site's own settings (validation, strict) turn a link to a missing page or anchor into a failure."""
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "index.md").write_text("# Home\n\n[a page](other.md) and [an anchor](#nowhere).\n")
    config.update(docs_dir=str(docs), nav=["index.md"], plugins=["search"])
    config.pop("hooks", None)
    (tmp_path / "mkdocs.yml").write_text(yaml.safe_dump(config))
    done = _mkdocs(tmp_path / "mkdocs.yml", tmp_path / "site")
    assert done.returncode != 0
    assert "'other.md', but the target is not found" in done.stderr
    assert "'#nowhere', but there is no such anchor" in done.stderr


def readme_links(text: str) -> list[str]:
    """The relative link targets of a Markdown text (``[text](target)``, images too), anchors dropped."""
    import re

    targets = re.findall(r"\]\(([^)\s]+)\)", text)
    return [t.split("#", 1)[0] for t in targets if not re.match(r"[a-z]+://", t) and not t.startswith("#")]


def test_every_link_of_the_readme_names_a_file():
    """README.md is not part of the site, so mkdocs does not check it: its links into docs/ are checked here."""
    assert readme_links("[a](docs/x.md#y) ![b](docs/f.png) [c](https://e.org) [d](#top)") == ["docs/x.md", "docs/f.png"]
    links = readme_links((ROOT / "README.md").read_text())
    assert "docs/index.md" in links
    missing = [t for t in links if not (ROOT / t).exists()]
    assert not missing, f"README.md links to files that do not exist: {missing}"
