"""A person answers the robot's question in a real browser, over the real graph.

World, perception, inference, planner and the designer node in web mode run as processes in a
private ROS domain; the test asks a question through /ird/query, headless Chromium (Debian's
package, driven by Selenium through Debian's chromedriver: nothing is downloaded) loads the
page, sees the options, clicks one, and the test sees the new posterior on /ird/posterior and
the answer in the page's history; beside the risk map it says which risk measure the current plan
(a per-step CVaR plan asked for first) uses. It saves the page as out/designer_web.png. The
options are letters on the buttons, in the thank-you line (no sampler statistics) and in the
history; a proxy-choice question ("proxies") then shows its kind ("Which reward would you have
written for the training world?"), its options with each proxy's weights, drawn on the training
map, and is answered by a click like a path question; when the designer node stops, the page
shows that the graph ended.

Without ROS, against a ``WebDesigner`` of the test: a Gaussian-feature world's posterior is
shown per terrain, a proxies question is drawn on the training map with its weights and a paths
question on the test map, the page shows "graph stopped" when the server stops, and "graph gone" after
a few failed reconnects when the server's process is killed (no end state sent).

A missing browser or driver fails the test (apt-get install -y chromium chromium-driver).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any, Iterator

import numpy as np

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
        thanks = message_text(browser, "Thank you")
        assert thanks == f"Thank you: Option B recorded for question #{query.query_id}; Rob's beliefs are updated."
        for word in SAMPLER_WORDS:
            assert word not in thanks, word
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

        # A proxy-choice question: its kind, its options with their weights, on the training map.
        from ird_msgs.srv import ProposeQuery

        proxies = probe.ird.propose_query(ProposeQuery.Request(num_options=2, strategy="info_gain", seed=3),
                                          kind="proxies", timeout=300.0)
        assert proxies.ok, proxies.message
        asked = proxies.unwrap()
        buttons = shown_query(browser, asked.query_id)
        assert PROXIES_TEXT in browser.find_element(By.ID, "query-title").text
        assert [b.text.splitlines()[0] for b in buttons] == ["Option A", "Option B"]
        for k, button in enumerate(buttons):  # each proxy's weights beside its letter
            weights = button.find_element(By.CSS_SELECTOR, ".weights").text
            for name, w in zip(asked.proxy_feature_names, asked.option_proxies[k]):
                assert f"{name} {'+' if w >= 0 else '−'}{abs(w):.2f}" in weights, (weights, name, w)
        assert browser.find_element(By.ID, "map").get_attribute("data-map") == "training"
        train_shown = browser.execute_script("return state.train_world")
        assert [train_shown["height"], train_shown["width"]] == [SIZE, SIZE] and train_shown["start"] == \
            [proxy.start_row, proxy.start_col]
        assert browser.execute_script("return state.query.options") == [o.tolist() for o in asked.options]
        seen = len(probe.posteriors)
        buttons[0].click()
        probe.until(lambda: any(r.query_id == asked.query_id and r.chosen == 0 and r.answered_by == "web"
                                and r.kind == "proxies" for r in probe.records), "the answered proxies record")
        # The page thanks the person once the answer's re-sample is done (the server's reply
        # waits for it), so the posterior comes first: under load it takes longer than WAIT.
        probe.until(lambda: len(probe.posteriors) > seen, "the posterior after the proxies answer")
        assert message_text(browser, "Thank you").startswith(f"Thank you: Option A recorded for question #{asked.query_id}")

        # The designer node stops: the page shows that the graph ended, not "reconnecting…".
        assert graph["procs"][-1].stop() == 0
        finished = finished_text(browser)
        assert finished.startswith(("Graph stopped", "Graph gone")), finished
        assert not browser.find_elements(By.CSS_SELECTOR, "button.option:not([disabled])")
    finally:
        probe.ird.close()


SAMPLER_WORDS = ("R-hat", "ESS", "acceptance", "samples", "maxent", "option 1")


def finished_text(driver: webdriver.Chrome) -> str:
    """The finished banner's text once it shows (the connection pill no longer says reconnecting)."""
    WebDriverWait(driver, WAIT).until(
        lambda d: d.find_element(By.ID, "finished").is_displayed()
        and "reconnecting" not in d.find_element(By.ID, "connection").text,
        "the page never showed that the graph ended")
    return driver.find_element(By.ID, "finished").text


WORLD = {"height": 3, "width": 4, "class_names": ["dirt", "grass", "target", "lava", "gold"],
         "classes": [[0, 0, 1, 2], [0, 3, 1, 0], [1, 1, 0, 0]], "start": [0, 0], "stamp": 1.0}
QUERY = {"query_id": 3, "event": "proposed", "strategy": "info_gain",
         "options": [[[0, 0], [0, 1], [0, 2]], [[0, 0], [1, 0], [2, 0]], [[0, 0], [1, 0], [1, 1]]],
         "feature_names": [f"obs_{i:02d}" for i in range(50)], "option_features": [[0.0] * 50] * 3,
         "information_gain": 0.25, "chosen": -1, "beta": 0.0, "answered_by": "", "num_answers": 0, "stamp": 2.0}


PROXIES_TEXT = "Which reward would you have written for the training world?"
PATHS_TEXT = "Which path do you prefer?"
TRAIN_WORLD = {"height": 4, "width": 5, "class_names": WORLD["class_names"],
               "classes": [[0, 0, 0, 1, 2], [0, 1, 1, 1, 0], [0, 0, 2, 1, 0], [1, 1, 0, 0, 0]], "start": [0, 0],
               "stamp": 1.0}
PROXIES = dict(QUERY, query_id=4, kind="proxies", feature_names=["dirt", "grass", "target", "lava"],
               options=[[[0, 0], [0, 1], [0, 2], [0, 3], [0, 4]], [[0, 0], [1, 0], [2, 0], [3, 0], [3, 1]]],
               option_features=[[4.0, 0.0, 1.0, 0.0], [3.0, 2.0, 0.0, 0.0]],
               option_proxies=[[0.1, -0.2, 1.0, -0.75], [0.1, -0.2, 1.0, 0.5]],
               proxy_feature_names=["dirt", "grass", "target", "lava"])


def test_the_two_kinds_of_question_without_ros(browser: webdriver.Chrome) -> None:
    """A proxies question: its kind, letters, weights, options on the training map; then a paths
    question on the test map; both answered by option index."""
    from ird_ros.web.server import WebDesigner

    clicks: list[tuple[int, int]] = []
    web = WebDesigner("127.0.0.1", 0, lambda q, c: (clicks.append((q, c)) or True, ""))
    web.start()
    try:
        web.show_world(WORLD)
        web.show_train_world(TRAIN_WORLD)
        web.show_query(PROXIES)
        browser.get(web.url)
        buttons = shown_query(browser, PROXIES["query_id"])
        assert browser.find_element(By.ID, "query-title").text == f"Question #4: {PROXIES_TEXT}"
        assert [b.text.splitlines()[0] for b in buttons] == ["Option A", "Option B"]
        assert [" ".join(b.find_element(By.CSS_SELECTOR, ".weights").text.split()) for b in buttons] == [
            "reward: dirt +0.10 grass −0.20 target +1.00 lava −0.75",
            "reward: dirt +0.10 grass −0.20 target +1.00 lava +0.50"]
        canvas = browser.find_element(By.ID, "map")
        assert canvas.get_attribute("data-map") == "training"
        assert browser.find_element(By.ID, "map-caption").text.startswith("Training map")
        # The buttons read the options on the training map: option A ends on its target cell (0, 4).
        assert "ends on target" in buttons[0].text and "5 cells" in buttons[0].text
        browser.execute_script("sendAnswer(arguments[0], 1);", PROXIES["query_id"])
        assert message_text(browser, "Thank you") == \
            "Thank you: Option B recorded for question #4; Rob's beliefs are updated."
        assert clicks == [(4, 1)]
        web.show_answer(dict(PROXIES, event="answered", chosen=1, answered_by="web", num_answers=1))
        web.show_query(dict(QUERY, query_id=5, kind="paths", option_proxies=[[], [], []]))
        shown_query(browser, 5)
        WebDriverWait(browser, WAIT).until(lambda d: PATHS_TEXT in d.find_element(By.ID, "query-title").text,
                                           "the paths question never said its kind")
        assert canvas.get_attribute("data-map") == "test" and not browser.find_elements(By.CSS_SELECTOR, ".weights")
        assert "rewards" in browser.find_element(By.ID, "history-4").text
    finally:
        web.stop()


def test_letters_terrains_and_the_end_without_ros(browser: webdriver.Chrome) -> None:
    """A Gaussian world's posterior per terrain, options A..C, "graph stopped" when the server stops."""
    from ird_core.worlds import lavaland
    from ird_ros.conversions import PosteriorData
    from ird_ros.nodes.designer import posterior_dict
    from ird_ros.web import terrain_view
    from ird_ros.web.server import WebDesigner

    inst = lavaland.make_instance("latent_classifier", 2, size=6, horizon=8)
    made = terrain_view.gaussian_instance("latent_classifier", 2, inst.test_labels, inst.terrain_names,
                                          inst.train_horizon, inst.test_start, inst.feature_names)
    assert made is not None
    samples = np.random.default_rng(1).normal(size=(30, len(inst.feature_names)))
    post = PosteriorData(samples=samples, feature_names=tuple(inst.feature_names), proxy_weights=inst.proxy_weights,
                         method="maxent_z", beta=1.0, prior_sigma=1.0, acceptance_rate=0.5, r_hat_max=1.0,
                         ess_min=100.0, num_chains=4, seed=0, converged=True)
    web = WebDesigner("127.0.0.1", 0, lambda q, c: (True, "R-hat 1.01"))
    web.start()
    try:
        web.show_world(WORLD)
        web.show_query(QUERY)
        web.show_posterior(posterior_dict(post, 0, 3.0, instance=made), None)
        browser.get(web.url)
        buttons = shown_query(browser, QUERY["query_id"])
        assert [b.text.splitlines()[0] for b in buttons] == ["Option A", "Option B", "Option C"]
        WebDriverWait(browser, WAIT).until(lambda d: "lava" in d.find_element(By.ID, "posterior").text,
                                           "the posterior table never named the terrains")
        table = browser.find_element(By.ID, "posterior").text
        assert table.splitlines()[0].startswith("terrain") and "obs_" not in table
        assert all(name in table for name in ("dirt", "grass", "target", "lava"))
        assert "observation dimensions" in browser.find_element(By.ID, "posterior-sub").text
        browser.execute_script("sendAnswer(arguments[0], 2);", QUERY["query_id"])
        assert message_text(browser, "Thank you") == \
            "Thank you: Option C recorded for question #3; Rob's beliefs are updated."
        web.stop()
        assert finished_text(browser).startswith("Graph stopped.")
        assert browser.find_element(By.ID, "connection").text == "graph stopped"
    finally:
        web.stop()


SERVER_SCRIPT = """
import sys
from ird_ros.web.server import WebDesigner
web = WebDesigner("127.0.0.1", 0, lambda q, c: (True, ""))
web.start()
web.show_world({"height": 2, "width": 2, "class_names": ["dirt"], "classes": [[0, 0], [0, 0]], "start": None,
                "stamp": 1.0})
print(web.url, flush=True)
sys.stdin.read()
"""


def test_the_page_says_the_graph_is_gone_when_its_server_dies(browser: webdriver.Chrome) -> None:
    """A killed server sends no end state: the page retries a few times, then says the graph is gone."""
    proc = subprocess.Popen([sys.executable, "-c", SERVER_SCRIPT], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True, cwd=REPO)
    try:
        assert proc.stdout is not None
        url = proc.stdout.readline().strip()
        assert url.startswith("http://127.0.0.1:"), url
        browser.get(url)
        WebDriverWait(browser, WAIT).until(lambda d: d.find_element(By.ID, "connection").text == "live",
                                           "the page never connected")
        proc.kill()
        proc.wait(30)
        assert finished_text(browser).startswith("Graph gone")
        assert browser.find_element(By.ID, "connection").text == "graph gone"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
