"""
The entity query behind get_entities / get_entities_states, ROS-free.

And the conversion of an EntityFilters message into it.
"""


from conftest import DEFAULT_SCENE, returns
from geometry_msgs.msg import Vector3
from msg_adapters import convert
import numpy as np
import pytest
from sim_node.core.errors import InvalidArgumentError
from sim_node.core.query import query, Region
from sim_node.core.world import World
from simulation_interfaces.msg import Bounds, EntityCategory, EntityFilters


@pytest.fixture(scope='module')
def world():
    return World.from_file(str(DEFAULT_SCENE))


def names(recs):
    return [r.name for r in recs]


def test_pattern_category_and_region(world):
    assert names(query(world, pattern='^box_')) == ['box_a', 'box_b']
    assert names(query(world, categories={'robot'})) == ['robot']
    assert names(query(world, categories={'dynamic'}, tags=('red',))) == []
    # A region selects what it overlaps, not only what has its origin inside (the standard):
    # box_b spans x 0.85-0.95, y -0.05-0.05, z 0.65-0.75 (origin 0.9, 0, 0.7); the arm
    # reaches x 0.747, the table's top is at z 0.42.
    edge = Region('box', np.array([0.94, 0.04, 0.74]), np.array([1.0, 0.2, 0.8]))
    assert names(query(world, region=edge)) == ['box_b']  # its corner only
    reversed_corners = Region('box', edge.b, edge.a)
    assert names(query(world, region=reversed_corners)) == ['box_b']
    above = np.array([0.9, 0.0, 0.79])
    assert names(query(world, region=Region('sphere', above, np.array([0.0401, 0, 0])))) == \
        ['box_b']  # its top face is 0.04 below the centre
    assert names(query(world, region=Region('sphere', above, np.array([0.0399, 0, 0])))) == []
    ball = Region('sphere', np.zeros(3), np.array([0.5, 0, 0]))
    assert names(query(world, region=ball)) == ['robot', 'table']  # the table from x 0.4
    with pytest.raises(InvalidArgumentError):
        query(world, pattern='(')


def test_entity_filters_message_becomes_the_same_query(world):
    static = EntityFilters(categories=[EntityCategory(
        category=EntityCategory.CATEGORY_STATIC_OBJECT)])
    assert names(query(world, **convert.entity_filters(static))) == ['table']
    msg = EntityFilters(filter='box')
    msg.categories = [EntityCategory(category=EntityCategory.CATEGORY_DYNAMIC_OBJECT)]
    msg.bounds = Bounds(type=Bounds.TYPE_SPHERE, points=[Vector3(x=0.9, y=0.0, z=0.7),
                                                         Vector3(x=0.05)])
    assert names(query(world, **convert.entity_filters(msg))) == ['box_b']
    msg.bounds = Bounds(type=Bounds.TYPE_BOX, points=[Vector3()])
    with pytest.raises(InvalidArgumentError):
        convert.entity_filters(msg)


def test_a_catastrophic_filter_is_refused_in_bounded_time(world):
    from sim_node.core.models import sources
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('a' * 40 + '_', sources.primitive('box', [0.05] * 3), position=[2, 2, 1])
    # The issue's: 2^40 steps with Python's re (a hang, not an answer)
    assert names(returns(lambda: query(w, pattern='^(a+)+$'))) == []
    with pytest.raises(InvalidArgumentError, match='took longer'):
        returns(lambda: query(w, pattern='^(a|aa)+$'))  # exponential for the regex package too
    assert names(query(w, pattern='^a+_$')) == ['a' * 40 + '_']
