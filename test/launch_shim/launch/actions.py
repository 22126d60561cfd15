"""``DeclareLaunchArgument`` and ``OpaqueFunction``, as the shim's runner reads them."""


class DeclareLaunchArgument:
    """A launch argument and its default."""

    def __init__(self, name, default_value='', description=''):
        self.name, self.default_value, self.description = name, default_value, description


class OpaqueFunction:
    """A function of the context that returns more entities."""

    def __init__(self, function):
        self.function = function
