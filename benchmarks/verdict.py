"""One line per target at the end of every benchmark: met or MISSED, with the figure."""

_LINES: list = []


def verdict(ok: bool, text: str) -> None:
    """Record a target's outcome and print its line now."""
    line = f'verdict: {"met   " if ok else "MISSED"} {text}'
    _LINES.append(line)
    print(line, flush=True)


def summary() -> None:
    """Print every verdict recorded in this process again, together, at the very end."""
    if _LINES:
        print(f'[verdicts] {sum(ln.startswith("verdict: met") for ln in _LINES)} of '
              f'{len(_LINES)} targets met')
        for line in _LINES:
            print(line)
