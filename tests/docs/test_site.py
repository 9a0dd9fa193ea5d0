"""The built documentation in a real browser: headless Chromium (Debian's ``chromium``, driven
by Playwright) loads every page of ``docs/_build/html`` served on 127.0.0.1 by this test.

It fails on a page that does not load, a broken internal link (a page or a file that is not
there, or an anchor no element of its page carries), a missing image or any other file of the
site that answers 404, and a search page that finds nothing for "PAPWC". It writes
screenshots of a few pages into ``docs/_build/screenshots/`` (to be looked at).

Build the site first: ``python -m sphinx -W --keep-going -b html docs docs/_build/html``.
"""

from __future__ import annotations

import functools
import http.server
import os
import shutil
import threading
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import unquote, urldefrag, urlsplit

import pytest

sync_api = pytest.importorskip("playwright.sync_api")

PROJECT = Path(__file__).resolve().parents[2]
SITE = PROJECT / "docs" / "_build" / "html"
SCREENSHOTS = PROJECT / "docs" / "_build" / "screenshots"
#: The flags Chromium runs with: no sandbox (root in CI), no GPU, nothing fetched on its own.
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                  "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync"]
#: Pages photographed: the start page, a tutorial, the API reference.
SHOTS = {"index": "index.html",
         "tutorial": "tutorials/tutorial_2_python_api.html",
         "reference": "reference/api.html",
         "scenario-fields": "reference/scenario-fields.html",
         "paper": "paper.html"}


def chromium_path() -> str:
    """Debian's chromium (``PAPWC_CHROMIUM`` to use another)."""
    found = os.environ.get("PAPWC_CHROMIUM") or shutil.which("chromium")
    if not found:
        pytest.fail("no chromium on PATH: apt-get install chromium (.ci/run does)")
    return found


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:  # noqa: A002
        """Say nothing per request."""


@pytest.fixture(scope="module")
def server() -> Iterator[str]:
    """The site served on 127.0.0.1 (a free port) while the tests run; its base URL."""
    if not (SITE / "index.html").is_file():
        pytest.fail(f"{SITE} holds no built site: python -m sphinx -W --keep-going -b html "
                    "docs docs/_build/html")
    handler = functools.partial(_QuietHandler, directory=str(SITE))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}/"
    finally:
        httpd.shutdown()
        httpd.server_close()
        thread.join(timeout=10)


@pytest.fixture(scope="module")
def browser(tmp_path_factory) -> Iterator[object]:
    """Headless Chromium with a new, empty profile."""
    profile = tmp_path_factory.mktemp("chromium-profile")
    with sync_api.sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            str(profile), executable_path=chromium_path(), headless=True,
            args=CHROMIUM_FLAGS, viewport={"width": 1280, "height": 900})
        try:
            yield context
        finally:
            context.close()


def site_pages() -> list[str]:
    """Every HTML page of the site, as paths relative to its root."""
    return sorted(str(p.relative_to(SITE)) for p in SITE.rglob("*.html")
                  if "_sources" not in p.parts and "_static" not in p.parts)


def local_target(url: str, base: str) -> tuple[str, str] | None:
    """(path relative to the site, fragment) of a link into the site; None for others."""
    if not url.startswith(base):
        return None
    without, fragment = urldefrag(url)
    path = unquote(urlsplit(without).path).lstrip("/")
    if path == "" or path.endswith("/"):
        path += "index.html"
    return path, fragment


def visit(context: object, url: str) -> tuple[dict, list[str]]:
    """Load ``url``; return what the page holds and every request of the site that failed."""
    page = context.new_page()
    failed: list[str] = []
    page.on("requestfailed", lambda request: failed.append(f"{request.url} (failed)"))
    page.on("response", lambda response: failed.append(f"{response.url} ({response.status})")
            if response.status >= 400 else None)
    try:
        response = page.goto(url, wait_until="load")
        assert response is not None and response.ok, f"{url}: {response and response.status}"
        found = page.evaluate("""() => ({
            links: Array.from(document.querySelectorAll('a[href]')).map(a => a.href),
            ids: Array.from(document.querySelectorAll('[id], a[name]'))
                      .map(e => e.id || e.getAttribute('name')),
            broken_images: Array.from(document.images)
                      .filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.src),
            title: document.title,
        })""")
    finally:
        page.close()
    return found, failed


def test_every_page_loads_with_its_images_and_every_internal_link_resolves(server, browser):
    pages = site_pages()
    assert "index.html" in pages and len(pages) >= 40, pages
    ids: dict[str, set[str]] = {}
    links: list[tuple[str, str, str]] = []
    problems: list[str] = []
    for path in pages:
        found, failed = visit(browser, server + path)
        ids[path] = set(found["ids"])
        problems += [f"{path}: image not shown: {src}" for src in found["broken_images"]]
        problems += [f"{path}: request {what}" for what in failed if what.startswith(server)]
        for href in found["links"]:
            target = local_target(href, server)
            if target is not None:
                links.append((path, *target))
    assert len(links) > 1000
    for source, target, fragment in links:
        if not (SITE / target).is_file():
            problems.append(f"{source}: link to a missing {target}")
        elif fragment and target.endswith(".html"):
            if target not in ids:  # a page not in the walk (none should be)
                ids[target] = set(visit(browser, server + target)[0]["ids"])
            if fragment not in ids[target]:
                problems.append(f"{source}: link to {target}#{fragment}, no such anchor")
    assert sorted(set(problems)) == []


def test_the_search_finds_papwc(server, browser) -> None:
    page = browser.new_page()
    try:
        page.goto(server + "search.html?q=PAPWC", wait_until="load")
        page.wait_for_function(
            "() => document.querySelectorAll('#search-results ul.search li').length > 0",
            timeout=60_000)
        hits = page.eval_on_selector_all("#search-results ul.search li a", "a => a.length")
        summary = page.inner_text("#search-results")
    finally:
        page.close()
    assert hits > 0, summary


def test_screenshots_of_a_few_pages(server, browser) -> None:
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    for name, path in SHOTS.items():
        page = browser.new_page()
        try:
            page.goto(server + path, wait_until="networkidle")
            page.screenshot(path=str(SCREENSHOTS / f"{name}.png"), full_page=False)
        finally:
            page.close()
        shot = SCREENSHOTS / f"{name}.png"
        assert shot.stat().st_size > 10_000, f"{shot}: nearly empty"
