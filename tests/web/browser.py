#!/usr/bin/env python3
"""A real browser for tests/web/: Debian's chromium, headless, driven by
Selenium through chromedriver. Reads one JSON request a line on stdin,
answers one JSON line on stdout ({"ok": ...} or {"error": ...}), so that
the Rust test holds a button, reads the bus, then releases.

With --accept-insecure-certs the browser accepts a certificate it does
not trust (a door's self-signed one), as WebDriver's acceptInsecureCerts.

Controls are found as a user (and a screen reader) finds them: by their
role and accessible name (the page's accessibility contract), never by CSS
classes.
"""

import json
import os
import signal
import sys
import time

from selenium import webdriver
from selenium.common.exceptions import TimeoutException, WebDriverException
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys
from selenium.webdriver.support.ui import WebDriverWait

WAIT_S = 20


def start():
    options = webdriver.ChromeOptions()
    if "--accept-insecure-certs" in sys.argv[1:]:
        # The door's self-signed certificate (tests/web/https.rs), as a
        # user accepts it once.
        options.accept_insecure_certs = True
    options.binary_location = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1280,900", "--no-first-run", "--disable-extensions",
                "--disable-background-networking", "--disable-component-update",
                "--disable-sync", "--disable-default-apps"):
        options.add_argument(arg)
    service = Service(os.environ.get("CHROMEDRIVER", "/usr/bin/chromedriver"))
    return webdriver.Chrome(options=options, service=service)


def region(d, name):
    """The card: a region named exactly `name`."""
    return WebDriverWait(d, WAIT_S).until(
        lambda d: next((e for e in d.find_elements(By.CSS_SELECTOR, "[role=region]")
                        if e.accessible_name == name), None))


def button(scope, name):
    def find(_):
        for e in scope.find_elements(By.TAG_NAME, "button"):
            if e.accessible_name == name and e.is_displayed():
                return e
        return None
    return WebDriverWait(d, WAIT_S).until(find)


def field(scope, label):
    def find(_):
        for e in scope.find_elements(By.TAG_NAME, "input"):
            if e.accessible_name == label and e.is_displayed():
                return e
        return None
    return WebDriverWait(d, WAIT_S).until(find)


def status_text(card):
    return card.find_element(By.CSS_SELECTOR, "[role=status]").text


def alert_text(card):
    return card.find_element(By.CSS_SELECTOR, "[role=alert]").text


def descendants(pid):
    """Every process below `pid` (from /proc), deepest last."""
    children = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                stat = f.read()
            ppid = int(stat[stat.rindex(")") + 2:].split()[1])
        except (OSError, ValueError):
            continue
        children.setdefault(ppid, []).append(int(entry))
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        for c in children.get(p, []):
            out.append(c)
            todo.append(c)
    return out


def handle(req):
    global d
    op = req["op"]
    if op == "open":
        # A spare tab first, so that closing the page's tab later keeps the
        # browser (and the page's tab is the visible one while it lives).
        page = d.current_window_handle
        d.switch_to.new_window("tab")
        spare.append(d.current_window_handle)
        d.switch_to.window(page)
        d.get(req["url"])
        return True
    if op == "sign_in":
        field(d, "User").send_keys(req["user"])
        field(d, "Password").send_keys(req["password"])
        button(d, "Sign in").click()
        return True
    if op == "sign_in_error":
        alert = d.find_element(By.ID, "sign-in-error")
        WebDriverWait(d, WAIT_S).until(lambda _: alert.text != "")
        return alert.text
    if op == "card_names":
        # The regions shown, once there is one; with `expect`, once they are
        # those (gimbal-web learns gcud's tours after the cards): the last
        # seen when they never become those.
        def shown(d):
            return [e.accessible_name for e in d.find_elements(By.CSS_SELECTOR, "[role=region]")
                    if e.is_displayed()]
        expect = req.get("expect")
        try:
            WebDriverWait(d, WAIT_S).until(lambda d: shown(d) == expect if expect else shown(d))
        except TimeoutException:
            pass
        return shown(d)
    if op == "place":
        # Where a card's button is on the page (CSS pixels).
        r = button(region(d, req["card"]), req["button"]).rect
        return [r["x"], r["y"]]
    if op == "hold":
        b = button(region(d, req["card"]), req["button"])
        ActionChains(d).move_to_element(b).perform()
        at = time.time()
        ActionChains(d).click_and_hold().perform()
        return at
    if op == "release":
        at = time.time()
        ActionChains(d).release().perform()
        return at
    if op == "key_down":
        card = region(d, req["card"])
        button(card, "Stop").send_keys("")  # focus inside the card
        ActionChains(d).key_down(getattr(Keys, req["key"])).perform()
        return time.time()
    if op == "key_up":
        at = time.time()
        ActionChains(d).key_up(getattr(Keys, req["key"])).perform()
        return at
    if op == "click":
        button(region(d, req["card"]), req["button"]).click()
        return True
    if op == "disabled":
        return not button(region(d, req["card"]), req["button"]).is_enabled()
    if op == "type":
        f = field(region(d, req["card"]), req["label"])
        f.clear()
        f.send_keys(req["text"])
        return True
    if op == "wait_status":
        card = region(d, req["card"])
        want = req["contains"]
        WebDriverWait(d, WAIT_S).until(lambda _: all(w in status_text(card) for w in want))
        return status_text(card)
    if op == "status":
        return status_text(region(d, req["card"]))
    if op == "wait_note":
        # The card's note (who controls the gimbal, as gcud says).
        card = region(d, req["card"])

        def note(_):
            e = next((e for e in card.find_elements(By.CSS_SELECTOR, "[role=note]") if e.is_displayed()), None)
            return e.text if e is not None and req["contains"] in e.text else None
        return WebDriverWait(d, WAIT_S).until(note)
    if op == "wait_text":
        # A region (a card, the Tours) once its visible text holds every one of `contains`.
        r = region(d, req["card"])
        WebDriverWait(d, WAIT_S).until(lambda _: all(w in r.text for w in req["contains"]))
        return r.text
    if op == "buttons":
        # The names of the buttons a card shows now.
        card = region(d, req["card"])
        return [e.accessible_name for e in card.find_elements(By.TAG_NAME, "button") if e.is_displayed()]
    if op == "speed_step":
        # Steps the card's Speed slider with the arrow keys (`steps`, + right)
        # and returns what the page shows beside it.
        card = region(d, req["card"])
        slider = field(card, "Speed")
        key = Keys.ARROW_RIGHT if req["steps"] > 0 else Keys.ARROW_LEFT
        for _ in range(abs(req["steps"])):
            slider.send_keys(key)
        return card.find_element(By.CSS_SELECTOR, "output").text
    if op == "wait_no_alert":
        # Waits until the card's alert is empty again (up to `seconds`).
        card = region(d, req["card"])
        WebDriverWait(d, req["seconds"]).until(lambda _: alert_text(card) == "")
        return True
    if op == "wait_alert":
        card = region(d, req["card"])
        WebDriverWait(d, WAIT_S).until(lambda _: alert_text(card) != "")
        return alert_text(card)
    if op == "click_picture":
        card = region(d, req["card"])
        pic = card.find_element(By.CSS_SELECTOR, "[role=img]")
        r = pic.rect
        # Offsets from the picture's centre, as fractions of its size.
        ActionChains(d).move_to_element_with_offset(
            pic, int(req["fx"] * r["width"]), int(req["fy"] * r["height"])).click().perform()
        return True
    if op == "map":
        # The card's pan/tilt map (found by its name), once it draws at
        # least `zones` keep-out zones: each zone's spans (its data
        # attributes, degrees) and the limits box as drawn.
        card = region(d, req["card"])
        pic = WebDriverWait(d, WAIT_S).until(
            lambda _: next((e for e in card.find_elements(By.CSS_SELECTOR, "[role=img]")
                            if e.accessible_name == "Pan/tilt map"), None))
        WebDriverWait(d, WAIT_S).until(
            lambda _: len(pic.find_elements(By.CSS_SELECTOR, "rect[data-pan-lo]")) >= req.get("zones", 1))
        zones = [{k: float(z.get_attribute("data-" + k)) for k in ("pan-lo", "pan-hi", "tilt-lo", "tilt-hi")}
                 for z in pic.find_elements(By.CSS_SELECTOR, "rect[data-pan-lo]")]
        limits = d.execute_script(
            "const r = arguments[0].querySelector('rect.limits');"
            "return r.getAttribute('display') === 'none' ? null :"
            " ['x', 'y', 'width', 'height'].map(k => Number(r.getAttribute(k)));", pic)
        return {"zones": zones, "limits": limits}
    if op == "fetch":
        # A request from the signed-in page itself (its cookie), with or
        # without the page's CSRF token: once the page knows who signed in
        # (a fetch right after signing in raced the page's own /api/me).
        WebDriverWait(d, WAIT_S).until(lambda d: d.execute_script("return typeof me !== 'undefined' && me !== null"))
        return d.execute_async_script(
            """
            const [path, body, withToken, done] = arguments;
            const headers = {'Content-Type': 'application/json'};
            if (withToken) headers['X-CSRF-Token'] = me.csrf;
            fetch(path, {method: 'POST', headers, body: JSON.stringify(body)})
              .then(async r => done({status: r.status, body: await r.text()}))
              .catch(e => done({status: 0, body: String(e)}));
            """, req["path"], req["body"], req["with_token"])
    if op == "close_page":
        # The tab is closed (no pointerup is ever sent); a blank one keeps the browser.
        at = time.time()
        d.close()
        d.switch_to.window(spare[0])
        return at
    if op == "kill_browser":
        # SIGKILL to the browser and every process of it: no page code runs.
        pids = descendants(d.service.process.pid)
        at = time.time()
        for p in pids:
            try:
                os.kill(p, signal.SIGKILL)
            except ProcessLookupError:
                pass
        return {"killed": len(pids), "at": at}
    if op == "screenshot":
        d.set_window_size(req.get("width", 1280), req.get("height", 900))
        return d.save_screenshot(req["path"])
    if op == "count_updates":
        # How often the position text changed over `seconds` (pushed updates).
        return d.execute_async_script(
            """
            const [name, seconds, done] = arguments;
            const card = [...document.querySelectorAll('[role=region]')].find(e => e.getAttribute('aria-label') === name);
            const status = card.querySelector('[role=status]');
            let n = 0;
            const seen = new MutationObserver(() => { n += 1; });
            seen.observe(status, {childList: true, characterData: true, subtree: true});
            setTimeout(() => { seen.disconnect(); done(n); }, seconds * 1000);
            """, req["card"], req["seconds"])
    if op == "watch_positions":
        # Each change of the position text over `seconds`: [wall time (s), text].
        return d.execute_async_script(
            """
            const [name, seconds, done] = arguments;
            const card = [...document.querySelectorAll('[role=region]')].find(e => e.getAttribute('aria-label') === name);
            const status = card.querySelector('[role=status]');
            const seen = [];
            const watch = new MutationObserver(() => { seen.push([Date.now() / 1000, status.textContent]); });
            watch.observe(status, {childList: true, characterData: true, subtree: true});
            setTimeout(() => { watch.disconnect(); done(seen); }, seconds * 1000);
            """, req["card"], req["seconds"])
    if op == "process_ids":
        # chromedriver and every process below it (the browser's).
        driver = d.service.process.pid
        return [driver] + descendants(driver)
    if op == "page_weight":
        return d.execute_script(
            "return performance.getEntriesByType('resource').concat(performance.getEntriesByType('navigation'))"
            ".filter(e => !e.name.includes('/api/')).map(e => [e.name, e.transferSize, e.encodedBodySize]);")
    raise ValueError(f"unknown op {op!r}")


d = start()
spare = []
print(json.dumps({"ok": "ready"}), flush=True)
for line in sys.stdin:
    req = json.loads(line)
    try:
        out = {"ok": handle(req)}
    except Exception as e:  # every failure goes back to the test, named
        out = {"error": f"{req.get('op')}: {type(e).__name__}: {e}"}
    print(json.dumps(out), flush=True)
    if req["op"] == "kill_browser":
        break
try:
    d.quit()
except WebDriverException:
    pass
