"""
Registers the `sim/...` Gymnasium ids as soon as Gymnasium's registry is imported.

Gymnasium before 1.0 loaded plugins from the ``gymnasium.envs`` entry point (declared in
setup.py); Gymnasium 1.x no longer does. So the project venv runs this module at start-up
(a ``.pth`` line written by ros_env/bootstrap.py): it imports nothing heavy, and only adds a
hook that registers the ids (as strings: nothing is imported) right after
``gymnasium.envs.registration`` loads. Then ``gymnasium.make('sim/PushBox-v0')`` works with no
import first.
"""

import importlib.abc
import sys

_TARGET = 'gymnasium.envs.registration'
#: (id, name, episode length): ``make_<name>`` in sim_node.gym.env (one env) and in
#: sim_node.gym.vector (``gymnasium.make_vec``).
IDS = (('sim/PushBox-v0', 'push_box', 200),
       ('sim/Reach-v0', 'reach', 200),
       ('sim/Pusher-v0', 'pusher', 100),    # Gymnasium's Pusher-v5 lengths
       ('sim/Reacher-v0', 'reacher', 50))   # and Reacher-v5's


def register_ids(registration) -> None:
    for env_id, name, steps in IDS:
        if env_id not in registration.registry:
            registration.register(id=env_id, entry_point=f'sim_node.gym.env:make_{name}',
                                  vector_entry_point=f'sim_node.gym.vector:make_{name}',
                                  max_episode_steps=steps)


class _Finder(importlib.abc.MetaPathFinder):

    def find_spec(self, fullname, path, target=None):
        if fullname != _TARGET:
            return None
        sys.meta_path.remove(self)  # find the real module, then wrap its loader
        try:
            import importlib.util
            spec = importlib.util.find_spec(fullname)
        finally:
            sys.meta_path.insert(0, self)
        if spec is None or spec.loader is None:
            return None
        real_exec = spec.loader.exec_module

        def exec_module(module):
            real_exec(module)
            register_ids(module)
            if self in sys.meta_path:
                sys.meta_path.remove(self)
        spec.loader.exec_module = exec_module
        return spec


def install() -> None:
    if _TARGET in sys.modules:
        register_ids(sys.modules[_TARGET])
    elif not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())


install()
