"""
Headless Chromium (Debian's ``chromium``) driven over its DevTools protocol, for screenshots.

The browser view's tests load a page, wait for it to draw, and read the screenshot's pixels.
Chromium runs with no GPU (WebGL through SwiftShader, which current Chromium only allows with
``--enable-unsafe-swiftshader``) and none of its background connections (this machine has no
network beyond package registries).
"""

import base64
import io
import itertools
import json
from pathlib import Path
import shutil
import socket
import subprocess
import tempfile
import time
import urllib.request

FLAGS = ['--headless', '--no-sandbox', '--disable-gpu', '--enable-unsafe-swiftshader',
         '--use-angle=swiftshader', '--disable-quic', '--no-first-run',
         '--disable-background-networking', '--disable-component-update', '--disable-sync',
         '--hide-scrollbars', '--mute-audio',
         # one renderer for the page whatever it loads (an error page too): the session stays
         '--disable-site-isolation-trials', '--disable-features=IsolateOrigins,site-per-process']


def executable() -> str:
    return shutil.which('chromium') or shutil.which('chromium-browser') or ''


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


class Browser:
    """One headless Chromium with one page; ``with`` closes it."""

    def __init__(self, width: int = 960, height: int = 600):
        port = _free_port()
        self._profile = tempfile.TemporaryDirectory(prefix='sim_chromium_',
                                                    ignore_cleanup_errors=True)
        self._proc = subprocess.Popen(
            [executable(), *FLAGS, f'--remote-debugging-port={port}',
             f'--user-data-dir={self._profile.name}', f'--window-size={width},{height}',
             'about:blank'], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 30
        while True:
            try:
                with urllib.request.urlopen(f'http://127.0.0.1:{port}/json/version',
                                            timeout=1) as r:
                    browser_url = json.load(r)['webSocketDebuggerUrl']
                break
            except (OSError, KeyError, ValueError):
                pass
            if time.monotonic() > deadline:
                self.close()
                raise RuntimeError('headless Chromium did not start')
            time.sleep(0.1)
        from websockets.sync.client import connect
        self._ws = connect(browser_url, max_size=None)
        self._ids = itertools.count(1)
        self._session = None
        # A page of our own, driven through the browser's connection (flattened sessions):
        # the page Chromium opens at start may be replaced while it starts.
        target = self.call('Target.createTarget', url='about:blank')['targetId']
        self._session = self.call('Target.attachToTarget', targetId=target,
                                  flatten=True)['sessionId']

    def call(self, method: str, **params) -> dict:
        msg_id = next(self._ids)
        message = {'id': msg_id, 'method': method, 'params': params}
        if self._session is not None and not method.startswith('Target.'):
            message['sessionId'] = self._session
        self._ws.send(json.dumps(message))
        while True:
            reply = json.loads(self._ws.recv(timeout=60))
            if reply.get('id') == msg_id:
                if 'error' in reply:
                    raise RuntimeError(f'{method}: {reply["error"]}')
                return reply.get('result', {})

    def load(self, url: str, timeout: float = 30.0) -> None:
        """Navigate to `url` and wait until the document has loaded."""
        self.call('Page.enable')
        self.call('Page.navigate', url=url)
        deadline = time.monotonic() + timeout
        while True:  # while the navigation commits the page may answer 'not attached'
            try:
                state = self.call('Runtime.evaluate', expression='document.readyState')
                if state.get('result', {}).get('value') == 'complete':
                    return
            except RuntimeError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f'{url} did not load within {timeout} s')
            time.sleep(0.1)

    def screenshot(self):
        """Return the page as an RGB numpy array (height, width, 3)."""
        import numpy as np
        from PIL import Image
        data = base64.b64decode(self.call('Page.captureScreenshot', format='png')['data'])
        return np.asarray(Image.open(io.BytesIO(data)).convert('RGB'))

    def drag(self, start: tuple, end: tuple, steps: int = 20) -> None:
        """Drag with the left button held from `start` to `end` (page pixels), as a hand does."""
        def mouse(kind: str, x: float, y: float, **more) -> None:
            self.call('Input.dispatchMouseEvent', type=kind, x=x, y=y, button='left', **more)
        mouse('mouseMoved', *start)
        mouse('mousePressed', *start, clickCount=1, buttons=1)
        for k in range(1, steps + 1):
            f = k / steps
            mouse('mouseMoved', start[0] + f * (end[0] - start[0]),
                  start[1] + f * (end[1] - start[1]), buttons=1)
            time.sleep(0.02)
        mouse('mouseReleased', *end, clickCount=1)

    def save(self, path: Path) -> None:
        from PIL import Image
        Image.fromarray(self.screenshot()).save(path)

    def close(self) -> None:
        ws = getattr(self, '_ws', None)
        if ws is not None:
            ws.close()
        self._proc.terminate()
        try:
            self._proc.wait(10)
        except subprocess.TimeoutExpired:
            self._proc.kill()
        self._profile.cleanup()

    def __enter__(self) -> 'Browser':
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def where(img, channel: int, margin: int = 60) -> tuple:
    """
    Find a strong colour (0 red, 1 green) in the middle of the page: (pixels, mean x in [-1, 1]).

    The page's corners are left out: they have viser's coloured axes logo.

    Lighting shades a colour: a pixel counts when that channel is `margin` above both others.
    """
    import numpy as np
    img = img.astype(int)
    others = [c for c in range(3) if c != channel]
    mask = (img[..., channel] > img[..., others[0]] + margin) & \
        (img[..., channel] > img[..., others[1]] + margin)
    w = img.shape[1]
    mask[:, :int(0.1 * w)] = False
    mask[:, int(0.9 * w):] = False
    ys, xs = np.nonzero(mask)
    if len(xs) < 300:  # smaller: the page's own icons (the green 'Connected' cloud)
        return 0, None
    return len(xs), float((xs.mean() - w / 2) / (w / 2))
