"""
ROS 2 parameter files as a controller manager reads them: a controllers YAML.

A ROS 2 parameter file maps node names to ``ros__parameters``: ``controller_manager:`` (its
``update_rate`` and each controller's ``type``), and one entry per controller (its
``joints``, ``interface_name``...). A node is found as ROS finds it: by its name, its full name
(``/ns/name``), or a ``/**`` wildcard, the wildcard's parameters first and the node's own over
them. Nested keys become ROS's dotted names (``constraints.goal_time``). ROS-free.
"""

from pathlib import Path
from typing import Callable, Iterable, Optional

import yaml

#: The largest parameter file read (bytes): a controllers YAML is a few kilobytes.
MAX_BYTES = 1_000_000
ROS_PARAMETERS = 'ros__parameters'


def load(path: str, readable: Callable[[Path], bool] = lambda p: True) -> dict:
    """
    Return a parameter file's contents.

    :param readable: whether the node may read a path (its resource folders).
    :raises ValueError: a file outside them, missing, too large, or not a YAML mapping, named.
    """
    p = Path(path).expanduser()
    if not p.is_absolute() or not readable(p):
        raise ValueError(f'parameter file {path!r} is outside the folders this node reads '
                         '(add its folder to resource_paths)')
    try:
        if p.stat().st_size > MAX_BYTES:
            raise ValueError(f'parameter file {path!r} is over {MAX_BYTES} bytes')
        doc = yaml.safe_load(p.read_text())
    except OSError as exc:
        raise ValueError(f'parameter file {path!r} cannot be read: {exc.strerror}') from None
    except yaml.YAMLError as exc:
        raise ValueError(f'parameter file {path!r} is not YAML: {exc}') from None
    if not isinstance(doc, dict):
        raise ValueError(f'parameter file {path!r} is not a mapping of node names')
    return doc


def node_parameters(docs: Iterable[dict], node: str, namespace: str = '') -> dict:
    """
    Return the dotted parameters `docs` (parsed files, in order) give the node `node`.

    Later files and the node's own entry win over earlier ones and wildcards (``/**`` for every
    node, ``/**/<node>`` for the node in any namespace).
    """
    ns = f'/{namespace.strip("/")}' if namespace.strip('/') else ''
    names = (node, f'/{node}', f'{ns}/{node}'.lstrip('/'), f'{ns}/{node}')
    out: dict = {}
    for doc in docs:
        wild = doc.get('/**')
        if isinstance(wild, dict):
            _merge(out, wild.get(ROS_PARAMETERS))
            for name in names:
                _merge(out, (wild.get(name) or {}).get(ROS_PARAMETERS)
                       if isinstance(wild.get(name), dict) else None)
        anywhere = doc.get(f'/**/{node}')  # the node in any namespace
        if isinstance(anywhere, dict):
            _merge(out, anywhere.get(ROS_PARAMETERS))
        for name in dict.fromkeys(names):
            entry = doc.get(name)
            if isinstance(entry, dict):
                _merge(out, entry.get(ROS_PARAMETERS))
    return out


def manager_rate(paths: Iterable[str], manager: str, namespace: str = '',
                 readable: Callable[[Path], bool] = lambda p: True) -> Optional[float]:
    """
    Return the ``update_rate`` a robot's controllers YAML gives its controller manager.

    None where none of its files may be read or none gives a positive number (the manager
    then takes its default); a file it cannot read is the manager's to refuse, by name.
    """
    docs = []
    for path in paths:
        try:
            docs.append(load(path, readable))
        except ValueError:
            continue
    rate = node_parameters(docs, manager, namespace).get('update_rate')
    if isinstance(rate, bool) or not isinstance(rate, (int, float)):
        return None
    return float(rate) if 0 < rate < float('inf') else None


def _merge(out: dict, params) -> None:
    if isinstance(params, dict):
        out.update(flatten(params))


def flatten(params: dict, prefix: str = '') -> dict:
    """Return nested parameters as ROS's dotted names."""
    out = {}
    for key, value in params.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            out.update(flatten(value, f'{name}.'))
        else:
            out[name] = value
    return out
