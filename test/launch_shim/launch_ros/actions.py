"""``Node``: what to start, as the shim's runner starts it."""


class Node:
    """A node to start: package, executable, parameters and arguments."""

    def __init__(self, package, executable, name=None, output=None, parameters=(),
                 arguments=(), **_):
        self.package, self.executable, self.name = package, executable, name
        self.parameters, self.arguments = list(parameters), list(arguments)
