"""
A child process that runs xacro on an untrusted description file (no sim_node imports).

Started by :mod:`.xacro_files` as ``python -I -S xacro_worker.py JOB``, with an empty
environment: JOB (JSON) gives the file (or text), the ``key:=value`` arguments, the folders it
may read, the module paths to import xacro from, and its limits (memory and CPU time: the
node's, :data:`.xacro_files.MEMORY_BYTES` and :data:`.xacro_files.CPU_SECONDS`). xacro
evaluates expressions from the file it processes (``${}``, ``$(eval)``: the restrictions can be
escaped), reads files (``load_yaml``, ``xacro:include``, ``$(find)``) and can grow without
bound, so before it reads anything this process limits itself:

* memory, CPU time, and files it may write (none);
* an audit hook that lets it open only regular files inside the readable folders (and the
  Python modules it imports), read-only, and refuses processes, sockets, ``ctypes``, and any
  change to the file system;
* XML with a DOCTYPE or entities is refused (defusedxml's minidom);
* ``$(find pkg)`` resolves to ``<folder>/<pkg>`` for each readable folder, as ``package://``
  does, then to the package's share folder where ROS is installed (which then becomes
  readable); ``$(env)`` sees an empty environment.

It writes the URDF to stdout and, last on stderr, one line ``read: [...]`` naming the files
it read (a JSON list of real paths: :mod:`.xacro_files` keeps the URDF while none changes); or
one line ``error: ...`` to stderr and exits 1.
"""

import errno
import json
import os
import re
import resource
import signal
import stat
import sys

#: This process's scheduling priority, below the node's: on a machine with few cores its work
#: took the CPU from the node's stepping and publishing threads (long /clock gaps in a spawn).
NICE = 10
_TOO_MUCH = 'it needs more memory than a description may take ({mib} MiB)'
_BLOCKED = ('subprocess.', 'socket.', 'ctypes.', 'os.exec', 'os.fork', 'os.posix_spawn',
            'os.spawn', 'os.system', 'os.remove', 'os.rmdir', 'os.rename', 'os.mkdir',
            'os.symlink', 'os.link', 'os.chmod', 'os.chown', 'os.truncate', 'os.utime',
            'os.kill', 'shutil.', 'pty.', 'webbrowser.', 'urllib.', 'http.', 'ftplib.',
            'smtplib.', 'sqlite3.', 'os.putenv', 'os.unsetenv', 'marshal.load')


def _inside(real: str, roots: list) -> bool:
    return any(real == r or real.startswith(r.rstrip('/') + '/') for r in roots)


def _guard(roots: list, code_roots: list, read: set) -> None:
    def hook(event: str, args: tuple) -> None:
        if event == 'open':
            path, mode = args[0], args[1] or 'r'
            if isinstance(path, int):
                return
            real = os.path.realpath(os.fsdecode(path))
            if _inside(real, code_roots) and real.endswith(('.py', '.pyc', '.so')):
                return
            name = os.fsdecode(path)
            if any(c in str(mode) for c in 'wax+'):
                raise PermissionError(errno.EACCES, 'a description file may not write files',
                                      name)
            if not _inside(real, roots):
                raise PermissionError(errno.EACCES, 'not inside the directories this node may '
                                      'read', name)
            try:
                mode_bits = os.stat(real).st_mode
            except OSError:
                return  # it does not exist: open says so
            if not stat.S_ISREG(mode_bits):
                raise PermissionError(errno.EACCES, 'not a regular file', name)
            read.add(real)
        elif event.startswith(_BLOCKED):
            raise PermissionError(f'a description file may not do {event}')
    sys.addaudithook(hook)


def main() -> None:
    os.nice(NICE)  # the node's physics and publishers first, whatever this costs
    job = json.loads(sys.argv[1])
    sys.path[:0] = job['paths']
    import defusedxml.minidom
    import xacro
    import xacro.substitution_args as subs
    import xml.dom.minidom
    import yaml  # noqa: F401 (xacro imports it lazily; imported before the guard)

    roots = [os.path.realpath(r) for r in job['roots']]
    code_roots = [os.path.realpath(p) for p in job['paths'] + [sys.prefix, sys.base_prefix]]

    shares = job.get('shares') or {}

    def find(pkg: str) -> str:
        for root in roots:
            folder = os.path.join(root, pkg)
            if os.path.isdir(folder):
                return folder
        if pkg in shares:  # an installed package (the parent read the ament index)
            folder = os.path.realpath(shares[pkg])
            roots.append(folder)
            return folder
        try:
            from ament_index_python.packages import get_package_share_directory
            folder = os.path.realpath(get_package_share_directory(pkg))
        except Exception:  # noqa: B902 (not installed: say so below)
            raise xacro.XacroException(f'package {pkg!r} is not found in the directories this '
                                       'node may read') from None
        roots.append(folder)
        return folder

    subs._eval_find = find  # $(find pkg)
    subs._eval_dict['find'] = find  # find() inside $(eval ...)
    xml.dom.minidom.parse = lambda f, *a, **k: defusedxml.minidom.parse(f, forbid_dtd=True)
    xml.dom.minidom.parseString = lambda s, *a, **k: defusedxml.minidom.parseString(
        s, forbid_dtd=True)
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    memory, cpu = int(job['memory_bytes']), int(job['cpu_seconds'])
    resource.setrlimit(resource.RLIMIT_AS, (memory, memory))
    resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu))
    resource.setrlimit(resource.RLIMIT_FSIZE, (0, 0))
    resource.setrlimit(resource.RLIMIT_NPROC, (0, 0))
    read = set()
    _guard(roots, code_roots, read)
    try:
        if job.get('file'):
            doc = xacro.process_file(job['file'], mappings=job['args'])
        else:
            doc = xacro.parse(job['text'])
            xacro.process_doc(doc, mappings=job['args'])
        sys.stdout.write(doc.toprettyxml(indent='  '))
        sys.stderr.write('read: ' + json.dumps(sorted(read)) + '\n')
    except MemoryError:
        _fail(_TOO_MUCH.format(mib=memory >> 20))
    except RecursionError:
        _fail('it nests macros or includes too deeply')
    except Exception as exc:  # noqa: B902 (whatever a hostile file raises is its answer)
        inner = exc
        while getattr(inner, 'exc', None) is not None:  # xacro wraps what failed
            inner = inner.exc
        if isinstance(inner, MemoryError):
            _fail(_TOO_MUCH.format(mib=memory >> 20))
        text = str(getattr(exc, 'msg', '') or exc)
        _fail(text if isinstance(exc, xacro.XacroException) else f'{type(exc).__name__}: {text}')


def _fail(why: str) -> None:
    text = ' '.join(re.sub(r"<class '[^']*'>:\s*", '', why).split())
    twice = re.match(r'^(.+?)\s*\1$', text)  # xacro repeats a message it wraps
    sys.stderr.write('error: ' + (twice.group(1) if twice else text)[:500] + '\n')
    sys.exit(1)


if __name__ == '__main__':
    main()
