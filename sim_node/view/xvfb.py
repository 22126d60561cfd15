"""
A virtual X display (Debian's ``xvfb``) for windows on machines without a screen.

The viewer's tests and benchmark open MuJoCo's window on one, as ``xvfb-run`` would::

    with VirtualDisplay() as display:   # sets DISPLAY for this process and its children
        window = Simulation.from_file('scenes/default.xml').view()
"""

import os
from pathlib import Path
import shutil
import subprocess
import time
from typing import Optional

ERR_NO_XVFB = ('no virtual display: Xvfb is not installed (Debian package xvfb: sudo apt-get '
               'install xvfb; make setup installs it when run as root)')


class VirtualDisplay:
    """Xvfb on the first free display number from 90; ``with`` sets and restores DISPLAY."""

    def __init__(self, width: int = 1280, height: int = 720):
        self._size = f'{int(width)}x{int(height)}x24'
        self._proc: Optional[subprocess.Popen] = None
        self._saved: Optional[str] = None
        self.name = ''

    @staticmethod
    def available() -> bool:
        return shutil.which('Xvfb') is not None

    def start(self) -> 'VirtualDisplay':
        if not self.available():
            raise RuntimeError(ERR_NO_XVFB)
        for number in range(90, 190):
            if Path(f'/tmp/.X{number}-lock').exists() or \
                    Path(f'/tmp/.X11-unix/X{number}').exists():
                continue
            proc = subprocess.Popen(['Xvfb', f':{number}', '-screen', '0', self._size,
                                     '-nolisten', 'tcp'], stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL)
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline and proc.poll() is None:
                if Path(f'/tmp/.X11-unix/X{number}').exists():
                    self._proc, self.name = proc, f':{number}'
                    self._saved = os.environ.get('DISPLAY')
                    os.environ['DISPLAY'] = self.name
                    return self
                time.sleep(0.05)
            proc.kill()
            proc.wait()
        raise RuntimeError('Xvfb did not start on any display from :90 to :189')

    def stop(self) -> None:
        """End the display; windows on it should be closed first."""
        if self._proc is None:
            return
        import sys
        if 'sim_node.view.window' in sys.modules:
            sys.modules['sim_node.view.window'].close_all()
        if 'glfw' in sys.modules:
            # GLFW keeps its connection to the display after its windows close; with the
            # display gone, the next GLFW call (at exit, at the latest) kills the process.
            sys.modules['glfw'].terminate()
        if self._saved is None:
            os.environ.pop('DISPLAY', None)
        else:
            os.environ['DISPLAY'] = self._saved
        self._proc.terminate()
        try:
            self._proc.wait(5)
        except subprocess.TimeoutExpired:
            self._proc.kill()
        self._proc = None

    def grab(self):
        """Return the whole screen as an RGB ``numpy`` array (height, width, 3)."""
        import numpy as np
        from PIL import ImageGrab
        return np.asarray(ImageGrab.grab(xdisplay=self.name).convert('RGB'))

    def __enter__(self) -> 'VirtualDisplay':
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
