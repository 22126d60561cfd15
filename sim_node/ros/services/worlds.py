"""
The world services: get_available_worlds, load_world, unload_world, get_current_world.

A world is read and checked as a spawn is (safe XML, budgets, every file read here from inside
the readable folders), MJCF or SDF (:func:`~sim_node.core.models.world_sources.world_source`),
built and compiled while the state is LOADING_WORLD, then swapped in, STOPPED as the standard
says; a world that fails to load leaves the running one as it was. An SDF world's own models with
sensors or systems come along as its entities; its ``<real_time_factor>`` paces it unless the
node was given a factor of its own (:meth:`SimNode.world_config <sim_node.ros.node.node>`).
"""

from typing import Callable

from msg_adapters import convert
from rclpy.node import Node
from simulation_interfaces.msg import Resource, WorldResource

from ...core.base.errors import FeatureUnsupportedError, SimError
from ...core.models import resources, sdf_files, sources, world_sources
from ...core.world import World
from ...session import Session

#: The longest resource_string a spawn or a load may send, in bytes.
MAX_RESOURCE_STRING_BYTES = 5_000_000
#: The files get_available_worlds lists in an additional source.
WORLD_SUFFIXES = ('.xml',) + sdf_files.SUFFIXES
#: The most characters of what a load left out that its answer carries (the log has them all).
MAX_NOTE_CHARS = 2000


class Worlds:
    """
    The world services of a node over a session.

    :param world_config: ``world_config(file_factor)`` the configuration a world is made
        with, given the real-time factor its file asks (None: none).
    :param on_state_change: called after a load changed the simulation state.
    """

    def __init__(self, node: Node, session: Session, readable: resources.Readable,
                 world_config: Callable, on_state_change: Callable[[], None]):
        self._node = node
        self._session = session
        self._readable = readable
        self._world_config = world_config
        self._on_state_change = on_state_change

    def available_worlds(self, request, response):
        if len(request.filter.tags):
            raise FeatureUnsupportedError('world tag filters are not supported (WORLD_TAGS is '
                                          'not listed): worlds carry no tags')
        for name, uri in resources.list_worlds(self._readable.scenes_dir):
            response.worlds.append(WorldResource(name=name, description=f'scene {name}',
                                                 world_resource=resource(uri)))
        failed = []
        for src in request.additional_sources:
            try:
                folder = resources.check_folder(src, list(self._readable.roots))
            except SimError as exc:
                if not request.continue_on_error:
                    raise
                failed.append(str(exc))  # the standard: go on, and succeed with the rest
                continue
            for f in sorted(p for p in folder.glob('*') if p.suffix in WORLD_SUFFIXES):
                response.worlds.append(WorldResource(name=f.stem, description=str(f),
                                                     world_resource=resource(f.as_uri())))
        response.result = convert.ok()
        response.result.error_message = '; '.join(failed)
        return response

    def load_world(self, request, response):
        """Read, check and compile the world (LOADING_WORLD meanwhile), then swap it in."""
        with self._session.loading():
            world, name, uri, dropped, skipped = self._read_world(request)
            # The standard: a loaded world is left STOPPED (at its initial state, not stepping).
            self._session.load(world, name, uri, stopped=True)
        self._on_state_change()
        response.world = WorldResource(name=name, world_resource=resource(uri))
        response.result = convert.ok()
        notes = []
        if dropped:
            notes.append('left out elements this simulator does not read: '
                         f'{world_sources.element_list(dropped)}')
        if skipped:  # as ignore_missing_or_unsupported_assets asked
            notes.append(f'left out for missing or unsupported assets: {"; ".join(skipped)}')
        if notes:
            note = '; '.join(notes)
            self._node.get_logger().warning(f'load_world {name}: {note}')
            response.result.error_message = note[:MAX_NOTE_CHARS]
        return response

    def _read_world(self, request) -> tuple:
        """Return (world, name, uri, elements left out, assets left out) of a load_world."""
        roots = list(self._readable.roots)
        # The same checks as a spawn: safe XML, budgets, and every file read here, from inside
        # the resource paths (MuJoCo opens nothing itself).
        modes = {'fail_on_unsupported_element': request.fail_on_unsupported_element,
                 'ignore_missing_assets': request.ignore_missing_or_unsupported_assets}
        places = self._readable.places
        if request.resource_string and not request.uri:  # the standard: a uri, when given, wins
            plan = world_sources.world_source(request.resource_string, None, roots,
                                              MAX_RESOURCE_STRING_BYTES, places=places, **modes)
            name, uri = plan.name or 'resource_string', ''
        else:
            path = resources.resolve_world(request.uri, roots, self._readable.scenes_dir)
            plan = world_sources.world_source(sources.read_model_text(path), str(path.parent),
                                              roots, places=places, name=path.name, **modes)
            name, uri = plan.name or path.stem, request.uri
        world = World.from_plan(plan, self._world_config(plan.real_time_factor), source=name)
        return world, name, uri, plan.dropped, plan.skipped

    def unload_world(self, request, response):
        self._session.unload()  # the publishers clear /tf_static and markers (ModelTopics)
        response.result = convert.ok()
        return response

    def current_world(self, request, response):
        loaded = self._session.require()
        response.world = WorldResource(name=loaded.name, world_resource=resource(loaded.uri))
        response.result = convert.ok()
        return response


def resource(uri: str) -> Resource:
    return Resource(uri=uri, resource_string='')
