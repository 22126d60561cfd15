"""The ament_python lint test for docstrings (ament_pep257's default conventions)."""

from ament_pep257.main import main
import pytest

from test_flake8 import PATHS, ROOT


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257(monkeypatch):
    monkeypatch.chdir(ROOT)
    rc = main(argv=[p for p in PATHS if (ROOT / p).exists()])
    assert rc == 0, 'Found code style errors / warnings'
