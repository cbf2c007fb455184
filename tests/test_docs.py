"""The documentation: every relative link in the Markdown resolves; the Sphinx site builds without a
warning; its generated reference pages hold every field and command; and the built tutorial and
reference pages load in headless Chromium with their images and internal links."""

from __future__ import annotations

import functools
import http.server
import importlib.util
import json
import re
import shutil
import subprocess
import sys
import threading
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urljoin, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists()
                                        else None)
MARKDOWN = sorted([ROOT / "README.md", *DOCS.rglob("*.md"), *(ROOT / "examples").rglob("*.md")])
_LINK = re.compile(r"(?<!\\)\[[^\]]*\]\(([^)\s]+)\)")


def _relative_links(path: Path) -> list[str]:
    """The relative link targets of a Markdown file, outside code blocks."""
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    text = re.sub(r"`[^`\n]*`", "", text)
    return [target for target in _LINK.findall(text)
            if not re.match(r"[a-z][a-z0-9+.-]*:", target) and not target.startswith("#")]


@pytest.mark.parametrize("path", MARKDOWN, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves(path):
    for target in _relative_links(path):
        file = target.split("#", 1)[0]
        assert (path.parent / unquote(file)).exists(), f"{path.relative_to(ROOT)}: {target} does not exist"


def test_every_page_has_one_title():
    # A page without a level-1 title has no name in the navigation (feature pages join it by glob).
    for path in DOCS.rglob("*.md"):
        if "_build" in path.parts:
            continue
        text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
        titles = re.findall(r"^# \S", text, flags=re.M)
        assert len(titles) == 1, f"{path.relative_to(ROOT)}: {len(titles)} level-1 titles"


def test_the_docs_extra_names_the_tools():
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert any(d.startswith("sphinx") for d in extras["docs"])
    assert any(d.startswith("myst-parser") for d in extras["docs"])


_MISSING = [name for name in ("sphinx", "myst_parser") if importlib.util.find_spec(name) is None]
needs_sphinx = pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed "
                                  "(python3 -m pip install -e '.[docs]'; .ci/run installs it)")


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site built once, as the README says, with warnings as errors."""
    out = tmp_path_factory.mktemp("site")
    done = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                           str(DOCS), str(out)], capture_output=True, text=True, timeout=600,
                          cwd=ROOT)
    assert done.returncode == 0, f"sphinx: {done.stdout[-3000:]}{done.stderr[-3000:]}"
    return out


def _text(page: Path) -> str:
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", page.read_text()))


@pytest.mark.slow
@needs_sphinx
def test_the_reference_pages_hold_every_field_and_command(site):
    from ecam.app.cli import build_parser
    from ecam.cam_fields import CAM_FIELDS
    from hil_sim.scene_fields import SCENE_FIELDS

    for page, fields in (("scene-file", SCENE_FIELDS), ("cam-file", CAM_FIELDS)):
        text = _text(site / "reference" / f"{page}.html")
        for field in fields:
            assert field.key in text and field.description.split()[0] in text, (page, field.name)
    cli = _text(site / "reference" / "cli.html")
    commands = [name for action in build_parser()._actions if hasattr(action, "choices")
                and isinstance(action.choices, dict) for name in action.choices]
    assert "firmware" in commands
    for name in commands:
        assert f"usage: ecam {name}" in cli, name
    # and every option of every command (the lately added: fit, sweep, transition, check --then,
    # sim --timing, drive --heartbeat-ms, export --master-counts ...)
    import html

    unescaped = html.unescape(cli)
    subparsers = next(a for a in build_parser()._actions if hasattr(a, "choices")
                      and isinstance(a.choices, dict)).choices
    for name, sub in subparsers.items():
        for action in sub._actions:
            for option in action.option_strings:
                assert option in unescaped, (name, option)
    api = _text(site / "reference" / "api.html")
    for name in ("compile_table", "CamTable", "load_scene", "run_scene", "find_max_speed"):
        assert name in api, name


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.links, self.images, self.ids = [], [], set()

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if attrs.get("id"):
            self.ids.add(attrs["id"])
        if tag == "a" and attrs.get("href"):
            self.links.append(attrs["href"])
        if tag == "img" and attrs.get("src"):
            self.images.append(attrs["src"])


@functools.cache
def _parsed(path: Path) -> _Links:
    parser = _Links()
    parser.feed(path.read_text())
    return parser


@pytest.mark.slow
@needs_sphinx
def test_every_internal_link_of_the_site_resolves(site):
    for page in sorted(site.rglob("*.html")):
        parsed = _parsed(page)
        for href in parsed.links + parsed.images:
            parts = urlsplit(href)
            if parts.scheme or parts.netloc:
                continue  # external: written, not fetched
            target = (page.parent / unquote(parts.path)).resolve() if parts.path else page
            assert target.exists(), f"{page.relative_to(site)}: {href}"
            if parts.fragment and target.suffix == ".html":
                assert parts.fragment in _parsed(target).ids, f"{page.relative_to(site)}: {href}"


# Opened in the browser: the pages a newcomer reads first.
BROWSED = ("index.html", "tutorial/index.html", "reference/scene-file.html",
           "reference/cam-file.html", "reference/cli.html", "reference/benchmarks.html",
           "howto/ci.html",
           # the topics the tutorial leads to, in its order
           "fit.html", "tuning.html", "sizing.html", "sweep.html", "cam_changes.html", "machine.html")

# Loads each page in an iframe, then reports its title, its images (loaded or not) and the
# status of every internal link (fetched from the same server), as JSON in the DOM.
HARNESS = """<!DOCTYPE html><html><body><pre id="result">pending</pre><script>
const pages = %s;
async function inspect(page) {
  const frame = document.createElement("iframe");
  frame.style.width = "1200px"; frame.style.height = "900px";
  document.body.appendChild(frame);
  await new Promise(done => { frame.onload = done; frame.src = page; });
  const doc = frame.contentDocument;
  await Promise.all([...doc.images].map(img => img.complete ? null :
      new Promise(done => { img.onload = done; img.onerror = done; })));
  const images = [...doc.images].map(img => [img.getAttribute("src"), img.naturalWidth]);
  const links = [...new Set([...doc.querySelectorAll("a[href]")].map(a => a.href)
      .filter(href => href.startsWith(location.origin)))];
  const broken = [];
  for (const link of links) {
    const url = new URL(link);
    const response = await fetch(url.origin + url.pathname);
    if (!response.ok) { broken.push(link + " " + response.status); continue; }
    if (url.hash.length > 1) {
      const text = await response.text();
      const id = decodeURIComponent(url.hash.slice(1));
      if (!text.includes('id="' + id + '"')) broken.push(link + " (no such anchor)");
    }
  }
  return {page, title: doc.title, h1: (doc.querySelector("h1") || {}).textContent || "",
          images, links: links.length, broken,
          height: doc.documentElement.scrollHeight};
}
(async () => {
  const out = [];
  for (const page of pages) { out.push(await inspect(page)); }
  document.getElementById("result").textContent = JSON.stringify(out);
})().catch(error => { document.getElementById("result").textContent = "ERROR " + error; });
</script></body></html>"""


@pytest.mark.slow
@needs_sphinx
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (Debian package "
                    "'chromium'; .ci/run installs it)")
def test_the_site_in_headless_chromium(site, tmp_path):
    (site / "_browser_check.html").write_text(HARNESS % json.dumps(list(BROWSED)))
    handler = functools.partial(_QuietHandler, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}/_browser_check.html"
        done = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
                               "--disable-background-networking", "--no-first-run",
                               f"--user-data-dir={tmp_path / 'profile'}",
                               "--virtual-time-budget=60000", "--dump-dom", url],
                              capture_output=True, text=True, timeout=180)
    finally:
        server.shutdown()
        server.server_close()
    assert done.returncode == 0, done.stderr[-2000:]
    found = re.search(r'<pre id="result">(.*?)</pre>', done.stdout, re.S)
    assert found, done.stdout[-2000:]
    result = found.group(1)
    assert result.startswith("["), result[:2000]
    pages = json.loads(result.replace("&amp;", "&").replace("&lt;", "<").replace("&gt;", ">")
                       .replace("&quot;", '"'))
    assert [p["page"] for p in pages] == list(BROWSED)
    for page in pages:
        assert page["title"].endswith("ecam " + _version()), page
        assert page["h1"].strip(), page
        assert page["links"] > 10 and not page["broken"], page
        assert page["height"] > 900, page  # rendered: more than one screen of content
        for src, width in page["images"]:
            assert width > 0, f"{page['page']}: image {src} did not load"
    benchmarks = next(p for p in pages if p["page"] == "reference/benchmarks.html")
    assert any("pareto" in src for src, _ in benchmarks["images"])
    fit = next(p for p in pages if p["page"] == "fit.html")
    assert any("fit-lift" in src for src, _ in fit["images"])


def _version() -> str:
    import ecam

    return ecam.__version__


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):  # keep the test's output to its assertions
        pass
