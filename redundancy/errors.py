"""One exception family: every failure a user can cause is a :class:`RedundancyError`.

Messages name the bad value, where it came from (a file and its table or key, or an option) and,
where there is a closed set, the valid choices.
"""

from collections.abc import Iterator
from contextlib import contextmanager


def placed(where: str, message: str) -> str:
    """``message`` led by ``where`` it came from (a file and its table or key), if known."""
    return f"{where}: {message}" if where else message


@contextmanager
def prefixed(where: str) -> Iterator[None]:
    """Re-raise a `RedundancyError` from inside, of its own kind, led by ``where`` (`placed`)."""
    try:
        yield
    except RedundancyError as error:
        if not where:
            raise
        raise type(error)(placed(where, str(error))) from None


class RedundancyError(Exception):
    """Base of every user-facing error of the toolkit."""


class RobotDescriptionError(RedundancyError):
    """A robot that cannot be loaded: unknown name, broken URDF, bad actuator declaration."""


class InvalidInputError(RedundancyError, ValueError):
    """An argument of the wrong shape, out of its domain, or not finite."""


class SingularConfigurationError(RedundancyError):
    """A configuration where a Jacobian the computation needs loses rank."""


class UnreachableError(RedundancyError):
    """A task point no configuration inside the joint and stroke limits reaches."""


class SchedulerLostError(RedundancyError):
    """A Dask scheduler, or the connection to it, lost while a design map ran: its finished
    chunks stay in the map's store for the rerun."""
