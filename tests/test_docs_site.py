"""The documentation site: built strictly, its graph tables generated, nothing loaded from the network,
and what a reader sees in a real browser.

- docs/architecture.md's node, topic, service and action tables equal what
  ``scripts/gen_graph_table.py`` generates from the graph's records now;
- the site builds with ``-W --keep-going`` (the build of ``scripts/build_docs.sh``; ``.ci/run`` relies on this test for it),
  and a small doc set with a broken page link, heading link, file link or Python reference fails
  to build with the same configuration (while the same set without the break builds);
- no built page or style sheet references an ``http(s)://`` (or protocol-relative) script, style
  sheet, font or image: nothing is downloaded when the site is viewed;
- headless Chromium (Debian's, through Debian's chromedriver: nothing is downloaded) shows the
  home page (its title, heading and mission picture) and an API page with a function's
  docstring, and saves out/site_home.png and out/site_api.png (docs/site_home.png is a copy).

A missing browser or driver fails the browser test (apt-get install -y chromium chromium-driver).
"""

from __future__ import annotations

import importlib.util
import inspect
import re
import subprocess
import sys
from pathlib import Path
from typing import Iterator

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
OUT = ROOT / "out"
CHROMIUM, CHROMEDRIVER = Path("/usr/bin/chromium"), Path("/usr/bin/chromedriver")
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--disable-quic",
                  "--no-first-run", "--disable-background-networking", "--disable-component-update",
                  "--disable-sync", "--window-size=1280,1000")
HOME_HEADING = "IRD: Inverse Reward Design as a ROS 2 navigation stack"
REMOTE = r"""(?:https?:)?//"""
REMOTE_REFERENCES = (
    re.compile(rf"""<script\b[^>]*\bsrc\s*=\s*["']?{REMOTE}""", re.I),
    re.compile(rf"""<link\b[^>]*\bhref\s*=\s*["']?{REMOTE}""", re.I),
    re.compile(rf"""<img\b[^>]*\bsrc\s*=\s*["']?{REMOTE}""", re.I),
    re.compile(rf"""url\(\s*["']?{REMOTE}""", re.I),
    re.compile(rf"""@import\s+(?:url\()?\s*["']?{REMOTE}""", re.I),
)


#: The tests that use the site pay for its build in their own time limit: the build's (one
#: sphinx process, about a minute idle; several under load), not the suite's 300 s per test.
SITE_BUILD_TIMEOUT_S = 900


def sphinx(source: Path, out: Path) -> subprocess.CompletedProcess[str]:
    """The build of scripts/build_docs.sh, into ``out``."""
    return subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                           str(source), str(out)], capture_output=True, text=True, timeout=SITE_BUILD_TIMEOUT_S)


def remote_references(text: str) -> list[str]:
    return [m.group(0) for pattern in REMOTE_REFERENCES for m in pattern.finditer(text)]


# --- the generated graph tables ------------------------------------------------------------------

def _generator():
    spec = importlib.util.spec_from_file_location("gen_graph_table", ROOT / "scripts" / "gen_graph_table.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_graph_tables_are_what_the_graph_records_say() -> None:
    gen = _generator()
    page = (DOCS / "architecture.md").read_text(encoding="utf-8")
    assert gen.render(page) == page, "run: .venv/bin/python scripts/gen_graph_table.py"
    for spec in gen.nodes.NODES:  # every node and every topic appears
        assert f"| `{spec.name}` | `{spec.module}` |" in page
    for topic in gen.names.TOPIC_TYPES:
        assert f"| `{topic}` |" in page


def test_a_stale_table_is_noticed() -> None:
    gen = _generator()
    page = (DOCS / "architecture.md").read_text(encoding="utf-8")
    stale = page.replace("| `world` | `ird_ros.nodes.world` |", "| `world` | `ird_ros.nodes.old_world` |")
    assert stale != page and gen.render(stale) == page
    with pytest.raises(SystemExit):
        gen.render(page.replace(gen.END, ""))


# --- the site ------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site")
    done = sphinx(DOCS, out)
    assert done.returncode == 0, f"the docs site does not build strictly:\n{done.stdout[-4000:]}\n{done.stderr[-8000:]}"
    return out


@pytest.mark.slow
@pytest.mark.timeout(SITE_BUILD_TIMEOUT_S)
def test_the_site_has_every_page_and_an_api_page_per_package(site: Path) -> None:
    for page in ("index", "install", "demo", "attaching", "library", "modelling", "spec", "architecture",
                 "worlds", "designer", "live_view", "experiments", "limits", "benchmarks", "dependencies",
                 "api/index", "api/ird_core.planning", "api/ird_ros.graph"):
        assert (site / f"{page}.html").is_file(), page
    for rst in (DOCS / "api").glob("*.rst"):
        assert (site / "api" / f"{rst.stem}.html").is_file()


@pytest.mark.slow
@pytest.mark.timeout(SITE_BUILD_TIMEOUT_S)
def test_no_page_loads_anything_from_the_network(site: Path) -> None:
    files = [p for p in site.rglob("*") if p.suffix in (".html", ".css", ".js")]
    assert len(files) > 20
    offenders = {str(p.relative_to(site)): refs for p in files
                 if (refs := remote_references(p.read_text(encoding="utf-8", errors="replace")))}
    assert offenders == {}
    mathjax = re.compile(r"<script\b[^>]*mathjax", re.I)  # Sphinx's default math renderer comes from a CDN
    assert not any(mathjax.search(p.read_text(encoding="utf-8", errors="replace")) for p in site.rglob("*.html"))


@pytest.mark.parametrize("snippet", [
    '<script src="https://cdn.example/x.js"></script>',
    '<link rel="stylesheet" href="//fonts.example/f.css">',
    '<style>@import "https://fonts.example/a.css";</style>',
    "@font-face {src: url(https://fonts.example/f.woff2)}",
    "<img src='http://example.org/x.png'>",
])
def test_the_network_check_finds_a_remote_reference(snippet: str) -> None:
    assert remote_references(snippet)


def test_the_network_check_leaves_local_files_and_plain_links_alone() -> None:
    page = ('<script src="_static/local.js"></script><link rel="stylesheet" href="_static/furo.css">'
            '<img src="demo_mission.png"><a href="https://example.org">a link to read is fine</a>'
            "<style>@font-face {src: url(../fonts/f.woff2)}</style>")
    assert remote_references(page) == []


BROKEN = {
    "a page that does not exist": "[broken](no_such_page.md)",
    "a heading that does not exist": "[broken](index.md#no-such-heading)",
    "a file that does not exist": "![broken](no_such_picture.png)",
    "a Python name that does not exist": "{py:func}`ird_core.planning.no_such_function`",
}


def _small_doc_set(folder: Path, body: str) -> Path:
    folder.mkdir()
    (folder / "conf.py").write_text(
        "import runpy\n"
        f"globals().update({{k: v for k, v in runpy.run_path({str(DOCS / 'conf.py')!r}).items()"
        " if not k.startswith('__')})\n"
        "ird_api_coverage = False  # a small doc set, not the project's site\n", encoding="utf-8")
    (folder / "index.md").write_text("# Home\n\n## A heading\n\n```{py:function} described_function()\n```\n\n"
                                     "```{toctree}\nother\n```\n", encoding="utf-8")
    (folder / "other.md").write_text(f"# Other\n\n## Here\n\nA link: {body}\n", encoding="utf-8")
    return folder


@pytest.mark.slow
@pytest.mark.parametrize("what", sorted(BROKEN))
def test_a_broken_reference_fails_the_build(what: str, tmp_path: Path) -> None:
    done = sphinx(_small_doc_set(tmp_path / "docs", BROKEN[what]), tmp_path / "html")
    assert done.returncode != 0
    assert "other.md" in done.stderr, done.stderr


@pytest.mark.slow
def test_the_same_doc_set_without_a_break_builds(tmp_path: Path) -> None:
    (tmp_path / "picture.png").write_bytes((DOCS / "demo_mission.png").read_bytes())
    body = ("[fine](index.md), [fine](index.md#a-heading), [fine](#here), ![fine](../picture.png), "
            "{py:func}`described_function`")
    folder = _small_doc_set(tmp_path / "docs", body)
    (tmp_path / "picture.png").rename(folder / "picture.png")
    (folder / "other.md").write_text((folder / "other.md").read_text().replace("../picture.png", "picture.png"))
    done = sphinx(folder, tmp_path / "html")
    assert done.returncode == 0, done.stderr


# --- in a real browser ---------------------------------------------------------------------------

@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory) -> Iterator[object]:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    for path in (CHROMIUM, CHROMEDRIVER):
        assert path.is_file(), f"{path} is missing: apt-get install -y chromium chromium-driver"
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}")
    # The explicit driver path keeps Selenium Manager from looking for (downloading) a driver.
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    try:
        yield driver
    finally:
        driver.quit()


def _loaded(driver: object, url: str) -> None:
    from selenium.webdriver.support.ui import WebDriverWait

    driver.get(url)  # type: ignore[attr-defined]
    WebDriverWait(driver, 60).until(lambda d: d.execute_script("return document.readyState") == "complete")


@pytest.mark.slow
@pytest.mark.timeout(SITE_BUILD_TIMEOUT_S)
def test_the_home_page_renders_in_a_browser(site: Path, browser: object) -> None:
    from selenium.webdriver.common.by import By

    _loaded(browser, (site / "index.html").as_uri())
    assert "IRD" in browser.title  # type: ignore[attr-defined]
    heading = browser.find_element(By.TAG_NAME, "h1").text  # type: ignore[attr-defined]
    assert heading.strip() == HOME_HEADING
    picture = browser.find_element(By.CSS_SELECTOR, "img[src$='demo_mission.png']")  # type: ignore[attr-defined]
    assert browser.execute_script("return arguments[0].complete && arguments[0].naturalWidth", picture) > 100  # type: ignore[attr-defined]
    sidebar = browser.find_element(By.CSS_SELECTOR, ".sidebar-tree").text  # type: ignore[attr-defined]
    for entry in ("Install, set-up and troubleshooting", "Limits and reliability", "API reference"):
        assert entry in sidebar
    OUT.mkdir(exist_ok=True)
    assert browser.save_screenshot(str(OUT / "site_home.png"))  # type: ignore[attr-defined]


@pytest.mark.slow
@pytest.mark.timeout(SITE_BUILD_TIMEOUT_S)
def test_an_api_page_shows_a_docstring_in_a_browser(site: Path, browser: object) -> None:
    from selenium.webdriver.common.by import By

    from ird_core.planning import plan_path

    _loaded(browser, (site / "api" / "ird_core.planning.html").as_uri())
    signature = browser.find_element(By.ID, "ird_core.planning.planners.plan_path")  # type: ignore[attr-defined]
    description = signature.find_element(By.XPATH, "following-sibling::dd").text
    first_line = inspect.getdoc(plan_path).splitlines()[0]
    words = re.sub(r"``|`", "", first_line).split()
    assert " ".join(words[:6]) in " ".join(description.split())
    OUT.mkdir(exist_ok=True)
    browser.execute_script("arguments[0].scrollIntoView()", signature)  # type: ignore[attr-defined]
    assert browser.save_screenshot(str(OUT / "site_api.png"))  # type: ignore[attr-defined]
