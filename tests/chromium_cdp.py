"""A real headless Chromium for the tests of the service's pages (Debian's ``chromium`` and ``chromium-driver``,
driven through Selenium) and the input they synthesize through the Chrome DevTools Protocol: touches
(``Input.dispatchTouchEvent``), mouse clicks and pens (``Input.dispatchMouseEvent``) and keys
(``Input.dispatchKeyEvent``), which the browser turns into the page's own pointer and keyboard events."""

import contextlib
import shutil
import time

import pytest

needed = pytest.mark.skipif(not (shutil.which("chromium") and shutil.which("chromedriver")),
                            reason="needs Debian's chromium and chromium-driver (./run tests installs them)")


@contextlib.contextmanager
def chromium(profile_dir):
    """A headless Chromium (800 × 600 CSS px) with its profile in ``profile_dir``, quit on leaving."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium")
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--window-size=800,600",
                 f"--user-data-dir={profile_dir}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)
    try:
        yield driver
    finally:
        driver.quit()


def touch_at(driver, x, y, seconds=0.2):
    """A finger down at (x, y) CSS px, held (a move every 10 ms), lifted: CDP's touch events."""
    point = [{"x": x, "y": y, "radiusX": 5, "radiusY": 5, "force": 0.6, "id": 1}]
    driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": point})
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchMove", "touchPoints": point})
        time.sleep(0.01)
    driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})


def finger_down(driver, x, y):
    """A finger put down at (x, y) CSS px and left there (:func:`finger_up` lifts it)."""
    point = [{"x": x, "y": y, "radiusX": 5, "radiusY": 5, "force": 0.6, "id": 1}]
    driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": point})


def finger_up(driver):
    driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})


def second_finger(driver, held, path):
    """A second finger along ``path`` ([(x, y), ...] CSS px: down at the first point, a move to each next one every
    10 ms, lifted at the last) while the first stays down at ``held`` (put there by :func:`finger_down`)."""
    first = {"x": held[0], "y": held[1], "radiusX": 5, "radiusY": 5, "force": 0.6, "id": 1}

    def second(x, y):
        return {"x": x, "y": y, "radiusX": 3, "radiusY": 3, "force": 0.5, "id": 2}

    driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": [first, second(*path[0])]})
    for x, y in path[1:]:
        time.sleep(0.01)
        driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchMove", "touchPoints": [first, second(x, y)]})
    driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": [second(*path[-1])]})


def tap(driver, box):
    """A tap at the middle of ``box`` ({left, top, width, height} CSS px)."""
    x, y = box["left"] + box["width"] / 2, box["top"] + box["height"] / 2
    point = [{"x": x, "y": y, "radiusX": 3, "radiusY": 3, "force": 0.5, "id": 2}]
    driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": point})
    driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})


def click(driver, x, y):
    """A left mouse click at (x, y) CSS px (a pointer of its own: a finger held on the page stays down)."""
    common = {"x": x, "y": y, "button": "left", "clickCount": 1}
    driver.execute_cdp_cmd("Input.dispatchMouseEvent", {"type": "mouseMoved", "x": x, "y": y})
    driver.execute_cdp_cmd("Input.dispatchMouseEvent", {"type": "mousePressed", "buttons": 1, **common})
    driver.execute_cdp_cmd("Input.dispatchMouseEvent", {"type": "mouseReleased", "buttons": 0, **common})


def pen_at(driver, x, y, seconds=0.2):
    """A pen pressed at (x, y) CSS px, held, lifted: CDP's mouse events with pointerType pen."""
    common = {"x": x, "y": y, "pointerType": "pen", "button": "left", "clickCount": 1, "force": 0.8}
    driver.execute_cdp_cmd("Input.dispatchMouseEvent", {"type": "mousePressed", "buttons": 1, **common})
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        driver.execute_cdp_cmd("Input.dispatchMouseEvent", {"type": "mouseMoved", "buttons": 1, **common})
        time.sleep(0.01)
    driver.execute_cdp_cmd("Input.dispatchMouseEvent", {"type": "mouseReleased", "buttons": 0, **common})


# the DOM's key, code and Windows virtual key code of the keys the tests press
KEYS = {"Enter": ("Enter", 13, "\r"), "ArrowLeft": ("ArrowLeft", 37, None), "ArrowRight": ("ArrowRight", 39, None),
        "Backspace": ("Backspace", 8, None), " ": ("Space", 32, " "), "-": ("Minus", 189, "-"),
        "=": ("Equal", 187, "="), ".": ("Period", 190, ".")}


def press_key(driver, key):
    """A key pressed and released: ``key`` is the DOM's name (``"Enter"``, ``"ArrowLeft"``, ``"2"``, ``"y"``...)."""
    if key in KEYS:
        code, vk, text = KEYS[key]
    elif len(key) == 1 and key.isdigit():
        code, vk, text = f"Digit{key}", ord(key), key
    elif len(key) == 1 and key.isalpha():
        code, vk, text = f"Key{key.upper()}", ord(key.upper()), key
    else:
        raise ValueError(f"no CDP key for {key!r}")
    down = {"type": "keyDown" if text else "rawKeyDown", "key": key, "code": code, "windowsVirtualKeyCode": vk}
    if text:
        down.update(text=text, unmodifiedText=text)
    driver.execute_cdp_cmd("Input.dispatchKeyEvent", down)
    driver.execute_cdp_cmd("Input.dispatchKeyEvent", {"type": "keyUp", "key": key, "code": code,
                                                      "windowsVirtualKeyCode": vk})
