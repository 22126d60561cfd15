"""``LaunchConfiguration``: an argument's value, read from the runner's context."""


class LaunchConfiguration:
    """An argument's value, looked up when performed."""

    def __init__(self, name):
        self.name = name

    def perform(self, context) -> str:
        return context[self.name]
