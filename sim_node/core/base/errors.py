"""
Typed errors of the world core.

Each maps to one simulation_interfaces Result code.

The node maps them in one table (``msg_adapters.results``); messages say what to fix.
"""


class SimError(Exception):
    """Base of every error the core raises on bad input or impossible requests."""


class FeatureUnsupportedError(SimError):
    """An option the simulator does not offer (answered FEATURE_UNSUPPORTED, 0)."""


class NotFoundError(SimError):
    """An entity, joint or resource that does not exist."""


class NameNotUniqueError(SimError):
    """An entity with this name exists and renaming was not allowed."""


class NameInvalidError(SimError):
    """A name that cannot be a MuJoCo or TF name."""


class NamespaceInvalidError(SimError):
    """A namespace that is not a valid ROS namespace."""


class NoResourceError(SimError):
    """A spawn or load request without any resource."""


class UnsupportedFormatError(SimError):
    """A resource in a format the simulator does not read."""


class ResourceParseError(SimError):
    """MJCF or URDF text that does not parse or compile."""


class MissingAssetsError(SimError):
    """A file the resource refers to does not exist or may not be read."""


class OutsideFoldersError(MissingAssetsError):
    """
    A file outside the readable folders, or a model URI that goes up a folder.

    Never read, and refused even where a load ignores missing assets.
    """


class UnsupportedAssetsError(SimError):
    """An asset that exists but cannot be used (bad mesh, too large, not a regular file)."""


class UnsupportedElementsError(SimError):
    """A world using an element MuJoCo does not know, when the caller asked to fail on one."""


class InvalidPoseError(SimError):
    """A pose that is non-finite, has a non-unit quaternion, or would interpenetrate."""


class InvalidArgumentError(SimError):
    """A value that is out of range, non-finite or of the wrong length."""


class CapacityError(SimError):
    """A request that would take the world past one of its configured limits."""


class IncorrectStateError(SimError):
    """A request that the simulation's current state does not allow."""


class NoWorldError(IncorrectStateError):
    """No world is loaded (NO_WORLD_LOADED where the service has that code, else 3)."""


class TransitionError(SimError):
    """A simulation state change the lifecycle refuses (SetSimulationState's own codes)."""


class AlreadyInStateError(TransitionError):
    """The simulation is in the requested state already (ALREADY_IN_TARGET_STATE, 101)."""


class StateTransitionError(TransitionError):
    """The transition was tried and failed (STATE_TRANSITION_ERROR, 102)."""


class IncorrectTransitionError(TransitionError):
    """The transition is not allowed from the current state (INCORRECT_TRANSITION, 103)."""


class OperationFailedError(IncorrectStateError):
    """
    A valid request the state does not allow, where the standard answers OPERATION_FAILED (4).

    Stepping while playing (StepSimulation, SimulateSteps) and a velocity for a static entity
    (SetEntityState) are such cases; a script may still catch them as IncorrectStateError.
    """


class DivergenceError(SimError):
    """The physics produced warnings or non-finite state; the loop pauses on it."""

    def __init__(self, message: str, step: int, report: dict):
        super().__init__(message)
        self.step = step
        self.report = report
