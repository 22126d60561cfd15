"""The ament_python lint test for code style (ament_flake8: 99 columns, google import order)."""

from pathlib import Path

from ament_flake8.main import main_with_errors
import pytest

ROOT = Path(__file__).resolve().parent.parent
#: Everything the package ships or runs, not the build folders and virtual environment.
PATHS = ['sim_node', 'msg_adapters', 'test', 'benchmarks', 'examples', 'ros_env', 'launch',
         'setup.py']


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(monkeypatch):
    monkeypatch.chdir(ROOT)
    rc, errors = main_with_errors(argv=[p for p in PATHS if (ROOT / p).exists()])
    assert rc == 0, \
        'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)
