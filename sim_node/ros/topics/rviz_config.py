"""
RViz configurations: the shipped one, with a robot's RobotModel display added on request.

RViz takes its displays from a file only, so ``ros2 launch sim sim.launch.py entity:=robot``
writes a copy of ``rviz/sim.rviz`` with a RobotModel display reading
``<namespace>/<entity>/robot_description`` (transient local, as the node latches it) and
placing its links at ``<frame_prefix><entity>/<link>``, the frames the node publishes.
"""

from msg_adapters.perception import topic_token

DISPLAYS = '  Displays:\n'

ROBOT_MODEL = """    - Alpha: 1
      Class: rviz_default_plugins/RobotModel
      Collision Enabled: false
      Description Source: Topic
      Description Topic:
        Depth: 1
        Durability Policy: Transient Local
        History Policy: Keep Last
        Reliability Policy: Reliable
        Value: {topic}
      Enabled: true
      Name: RobotModel {entity}
      TF Prefix: {prefix}
      Update Interval: 0
      Value: true
      Visual Enabled: true
"""


def with_robot_model(config: str, entity: str, namespace: str = '',
                     frame_prefix: str = '') -> str:
    """
    Return the RViz configuration `config` (text) with a RobotModel display of `entity`.

    RViz joins its TF prefix and a link's name with '/': the prefix is
    ``<frame_prefix><entity>``.
    """
    if DISPLAYS not in config:
        raise ValueError('the RViz configuration has no Displays list')
    ns = '/' + namespace.strip('/') if namespace.strip('/') else ''
    display = ROBOT_MODEL.format(topic=f'{ns}/{topic_token(entity)}/robot_description',
                                 entity=entity, prefix=f'{frame_prefix}{entity}')
    return config.replace(DISPLAYS, DISPLAYS + display, 1)
