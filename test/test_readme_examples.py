"""
The README's and docs' examples, run exactly as written: shell blocks in bash, Python blocks.

Shell blocks that talk to the node run against ``make run`` (the README's own command, started
here in the background); ``ros2`` is ``test/ros2_shim/ros2`` where ros2cli is not installed.
Each ``make run`` line of a block is started in the background, as a second shell would.
"""

import os
from pathlib import Path
import re
import shutil
import signal
import subprocess
import sys
import time

from conftest import ROOT
import pytest

DOCUMENTS = [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))]
BLOCKS = [(kind, text) for doc in DOCUMENTS
          for kind, text in re.findall(r'```(bash|python)\n(.*?)```', doc.read_text(), re.S)]
SHIM = ROOT / 'test' / 'ros2_shim'


def shell_blocks() -> list:
    """Blocks that run against a node (not set-up, not the ROS-machine install)."""
    return [text for kind, text in BLOCKS if kind == 'bash'
            and ('ros2 ' in text or 'SimClient' in text or 'make run ARGS' in text)
            and '/opt/ros' not in text]


def python_blocks() -> list:
    return [text for kind, text in BLOCKS if kind == 'python']


class Session:
    """A process group of shells and nodes started for one block; all stopped at the end."""

    def __init__(self, tmp_path: Path):
        self.tmp, self.procs = tmp_path, []
        self.env = dict(os.environ, SIM_README_LOGS=str(tmp_path))
        if shutil.which('ros2') is None:
            self.env['PATH'] = f'{SHIM}:{self.env["PATH"]}'

    def start(self, command: str, name: str) -> None:
        log = open(self.tmp / f'{name}.log', 'w')
        self.procs.append(subprocess.Popen(['bash', '-c', command], cwd=ROOT, env=self.env,
                                           stdout=log, stderr=subprocess.STDOUT,
                                           start_new_session=True))

    def run(self, script: str, timeout: float = 180) -> subprocess.CompletedProcess:
        """Run a script in a session of its own; what it leaves running is stopped later."""
        p = subprocess.Popen(['bash', '-c', 'set -eo pipefail\n' + script], cwd=self.tmp,
                             env=self.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, start_new_session=True)
        self.procs.append(p)
        out, err = p.communicate(timeout=timeout)
        return subprocess.CompletedProcess(p.args, p.returncode, out, err)

    def stop(self) -> None:
        """SIGINT to every group (nodes end cleanly), SIGKILL to what is left after 10 s."""
        for p in self.procs:
            _signal_group(p.pid, signal.SIGINT)
        deadline = time.monotonic() + 10
        for p in self.procs:
            while _signal_group(p.pid, 0) and time.monotonic() < deadline:
                time.sleep(0.05)
            _signal_group(p.pid, signal.SIGKILL)
            p.wait()

    def logs(self) -> str:
        return '\n'.join(f.read_text() for f in sorted(self.tmp.glob('*.log')))


def _signal_group(pgid: int, sig: int) -> bool:
    """Signal a process group; False if none of it is left."""
    try:
        os.killpg(pgid, sig)
        return True
    except ProcessLookupError:
        return False


def as_script(block: str) -> str:
    """Return the block with each `make run ...` line sent to the background (a terminal)."""
    lines = []
    for i, line in enumerate(block.splitlines()):
        if line.startswith('make run'):
            line = f'( {line} ) > "$SIM_README_LOGS/make_run_{i}.log" 2>&1 &'
        lines.append(line)
    return '\n'.join(lines)


@pytest.mark.parametrize('block', shell_blocks(), ids=lambda b: b.splitlines()[0][:40])
def test_readme_shell_block_runs_as_written(block, tmp_path):
    session = Session(tmp_path)
    own_node = 'make run ARGS' in block
    try:
        if not own_node or '__ns:=' in block:  # the second world needs the first running
            session.start('make run', 'default_node')
        script = f'cd {ROOT}\n' + as_script(block)
        if '__ns:=/robot2' in block:  # then the second answers under its namespace
            script += ('\nros2 service call /robot2/get_simulation_state '
                       'simulation_interfaces/srv/GetSimulationState "{}"')
        out = session.run(script)
        assert out.returncode == 0, (out.stdout[-3000:], out.stderr[-3000:], session.logs())
    finally:
        session.stop()


@pytest.mark.parametrize('block', [b for b in python_blocks() if 'SimClient' not in b],
                         ids=lambda b: b.splitlines()[0][:40])
def test_readme_python_block_runs_as_written(block):
    out = subprocess.run([sys.executable, '-c', block], cwd=ROOT, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]


@pytest.mark.parametrize('block', [b for b in python_blocks() if 'SimClient' in b],
                         ids=lambda b: b.splitlines()[0][:40])
def test_readme_client_block_runs_as_written(block, tmp_path):
    session = Session(tmp_path)
    try:
        session.start('make run', 'default_node')
        out = subprocess.run([sys.executable, '-c', block], cwd=ROOT, env=session.env,
                             capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, (out.stderr[-3000:], session.logs())
        assert "'position'" in out.stdout  # it printed the crate's state
    finally:
        session.stop()
