"""A person answers the robot's question in a real browser, over the real graph.

World, perception, inference, planner and the designer node in web mode run as processes in a
private ROS domain; the test asks a question through /ird/query, headless Chromium (Debian's
package, driven by Selenium through Debian's chromedriver: nothing is downloaded) loads the
page, sees the options, clicks one, and the test sees the new posterior on /ird/posterior and
the answer in the page's history; beside the risk map it says which risk measure the current plan
(a per-step CVaR plan asked for first) uses. It saves the page as out/designer_web.png.

A missing browser or driver fails the test (apt-get install -y chromium chromium-driver).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import pytest
import yaml
from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

REPO = Path(__file__).resolve().parents[2]
CHROMIUM, CHROMEDRIVER = Path("/usr/bin/chromium"), Path("/usr/bin/chromedriver")
SCREENSHOT = REPO / "out" / "designer_web.png"
SIZE, HORIZON, SEED = 8, 10, 3
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--disable-quic",
                  "--no-first-run", "--disable-background-networking", "--disable-component-update",
                  "--disable-sync", "--window-size=1280,1000")
WAIT = 60.0  # seconds a page condition may take (the page updates on WebSocket pushes)


@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory) -> Iterator[webdriver.Chrome]:
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


@pytest.fixture(scope="module")
def graph(ros_domain: Any, tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    from ird_ros.testing import running_nodes

    tmp = tmp_path_factory.mktemp("designer_web")
    params = yaml.safe_load((REPO / "msgs_config/params/graph.yaml").read_text())
    params["world"]["ros__parameters"].update(condition="side_effects", seed=SEED, height=SIZE, width=SIZE,
                                              horizon=HORIZON)
    params["inference"]["ros__parameters"].update(num_chains=4)
    # Port 0: the server binds a free port itself (no race with other processes); its URL is logged.
    params["designer"]["ros__parameters"].update(mode="web", host="127.0.0.1", port=0)
    params_file = tmp / "graph.yaml"
    params_file.write_text(yaml.safe_dump(params))
    nodes = [(name, ["-m", f"ird_ros.nodes.{name}", "--ros-args", "--params-file", str(params_file)])
             for name in ("world", "perception", "inference", "planner", "designer")]
    with running_nodes(ros_domain, *nodes) as procs:
        designer = procs[-1]
        line = designer.wait_for_output("designer web page at", timeout=60.0)
        url = line.split("designer web page at ", 1)[1].split()[0]
        assert url.startswith("http://127.0.0.1:") and not url.startswith("http://127.0.0.1:0/"), line
        yield {"url": url, "procs": procs}


class Probe:
    """The test's ROS side: an IrdClient collecting the posteriors, risk maps and query history."""

    def __init__(self, ctx: Any, procs: list[Any]) -> None:
        from ird_ros.client import IrdClient
        from ird_ros.graph import names

        self.procs = procs
        self.ird = IrdClient(context=ctx, node_name="designer_web_probe", processes=procs)
        self.ird.subscribe(names.TOPIC_POSTERIOR, names.TOPIC_RISK_MAP, names.TOPIC_QUERIES)
        self.posteriors: list[Any] = self.ird.received(names.TOPIC_POSTERIOR)
        self.risk_maps: list[Any] = self.ird.received(names.TOPIC_RISK_MAP)
        self.records: list[Any] = self.ird.received(names.TOPIC_QUERIES)

    def until(self, condition: Any, what: str, timeout: float = 120.0) -> None:
        self.ird.spin_until(condition, timeout=timeout, what=what)


def infer_first_posterior(probe: Probe) -> Any:
    """The proxy's posterior (/ird/infer), which the questions start from; returns the proxy."""
    from ird_ros.client import infer_request
    from ird_ros.graph import names

    proxy = probe.ird.proxy(timeout=60)
    train = probe.ird.latest(names.TOPIC_TRAIN_FEATURES, timeout=60)
    request = infer_request(train, (proxy.start_row, proxy.start_col), proxy.horizon, proxy.weights,
                            beta=5.0, method="maxent_z", num_samples=100, seed=11)
    result = probe.ird.infer(request, timeout=300.0)
    assert result.ok, result.message
    return proxy


def ask(probe: Probe, proxy: Any, seed: int) -> Any:
    """A question (/ird/query, info_gain, 2 options) on the test map; the decoded query."""
    from ird_ros.client import query_request

    request = query_request((proxy.test_start_row, proxy.test_start_col), horizon=proxy.test_horizon,
                            num_options=2, strategy="info_gain", seed=seed)
    result = probe.ird.propose_query(request, timeout=300.0)
    assert result.ok, result.message
    return result.unwrap()


def shown_query(driver: webdriver.Chrome, query_id: int) -> list[Any]:
    """The option buttons once the page shows question ``query_id``."""
    WebDriverWait(driver, WAIT).until(
        lambda d: d.find_elements(By.CSS_SELECTOR, f'button.option[data-query-id="{query_id}"]'),
        f"the page never showed question {query_id}")
    return driver.find_elements(By.CSS_SELECTOR, "button.option")


def message_text(driver: webdriver.Chrome, words: str) -> str:
    WebDriverWait(driver, WAIT).until(lambda d: words in d.find_element(By.ID, "message").text,
                                      f"the page's message never said {words!r}")
    return driver.find_element(By.ID, "message").text


def test_person_answers_in_the_browser(graph: dict[str, Any], browser: webdriver.Chrome, ros_ctx: Any) -> None:
    from ird_ros.client import plan_request

    probe = Probe(ros_ctx, graph["procs"])
    try:
        proxy = infer_first_posterior(probe)
        probe.until(lambda: probe.posteriors and probe.risk_maps, "the first posterior and the planner's risk map")
        planned = probe.ird.plan(plan_request((proxy.test_start_row, proxy.test_start_col), proxy.test_horizon,
                                              "per_step", "none", label="web_cvar", risk="cvar", risk_level=0.25),
                                 timeout=120.0)
        assert planned.ok and planned.response.risk == "cvar", planned.message
        query = ask(probe, proxy, seed=1)

        browser.get(graph["url"])
        # Beside the risk map: the risk measure of the current plan (/ird/plan_info via the designer).
        WebDriverWait(browser, WAIT).until(
            lambda d: d.find_element(By.ID, "risk-plan").text == "plan: per-step CVaR alpha=0.25",
            "the page never said which risk measure the plan uses")
        buttons = shown_query(browser, query.query_id)
        assert [b.text.splitlines()[0] for b in buttons] == ["Option A", "Option B"]
        assert len(buttons) == len(query.options)
        assert "Question #%d" % query.query_id in browser.find_element(By.ID, "query-title").text

        # The person clicks Option B; the answer reaches /ird/answer and a new posterior follows.
        seen = len(probe.posteriors)
        buttons[1].click()
        probe.until(lambda: len(probe.posteriors) > seen, "the posterior after the web answer")
        probe.until(lambda: any(r.query_id == query.query_id and r.chosen == 1 and r.answered_by == "web"
                                for r in probe.records), "the answered record on /ird/queries")
        assert "Thank you" in message_text(browser, "Thank you")
        WebDriverWait(browser, WAIT).until(lambda d: d.find_elements(By.ID, f"history-{query.query_id}"),
                                           "the answer never appeared in the page's history")
        row = browser.find_element(By.ID, f"history-{query.query_id}").text
        assert "Option B" in row and "web" in row
        # The page shows the posterior that followed the answer (pushed, no reload).
        stamp = probe.posteriors[-1].header.stamp
        stamp_s = stamp.sec + stamp.nanosec * 1e-9
        WebDriverWait(browser, WAIT).until(
            lambda d: abs((d.execute_script("return state.posterior && state.posterior.stamp") or 0) - stamp_s) < 1e-6,
            "the page never showed the new posterior")

        # A stale click (the same question again, as a double click or an old tab would send)
        # is refused on the page and changes nothing.
        answered = len([r for r in probe.records if r.event == "answered"])
        browser.execute_script("sendAnswer(arguments[0], 0);", query.query_id)
        assert "already answered" in message_text(browser, "Not recorded")
        browser.execute_script("sendAnswer(arguments[0], 0);", query.query_id + 1000)
        assert "unknown query" in message_text(browser, "unknown query")
        probe.until(lambda: True, "a spin")
        assert len([r for r in probe.records if r.event == "answered"]) == answered

        # The next question, for the picture: map, options, risk map, belief and history at once.
        second = ask(probe, proxy, seed=2)
        shown_query(browser, second.query_id)
        assert "hidden" in browser.find_element(By.ID, "message").get_attribute("class")
        # The whole page in one picture: a viewport as tall as the page.
        height = int(browser.execute_script("return document.documentElement.scrollHeight"))
        browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                                {"width": 1280, "height": height, "deviceScaleFactor": 1, "mobile": False})
        shown_query(browser, second.query_id)
        SCREENSHOT.parent.mkdir(exist_ok=True)
        assert browser.save_screenshot(str(SCREENSHOT)), "screenshot failed"
    finally:
        probe.ird.close()
