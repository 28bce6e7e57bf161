"""Error and warning types raised by every layer of policylab.

Every error a user can trigger with bad input is a subclass of :class:`PolicylabError`
and of ``ValueError`` or ``TypeError``, and its message says what was expected, what
was given, and where (named by label).
"""

from __future__ import annotations


class PolicylabError(Exception):
    """Base class of every error policylab raises on purpose."""


class InvalidMDPError(PolicylabError, ValueError):
    """A finite MDP's definition is malformed (dynamics, labels, gamma, shapes)."""


class ShapeError(InvalidMDPError):
    """Arrays given to a constructor have shapes that do not fit together."""


class InvalidPolicyError(PolicylabError, ValueError):
    """A policy does not fit its MDP (rows, probabilities, unavailable actions)."""


class UnknownLabelError(PolicylabError, ValueError):
    """A state or action label that the MDP does not have."""


class InvalidActionError(PolicylabError, ValueError):
    """An action that is not available in the current state was taken."""


class UnknownProblemError(PolicylabError, ValueError):
    """A built-in problem name that is not registered."""


class InvalidArgumentError(PolicylabError, ValueError):
    """A function argument outside its allowed range or of the wrong kind."""


class CheckpointError(PolicylabError, ValueError):
    """A checkpoint or saved file is missing, corrupt, or unsafe to load."""


class NonFiniteError(PolicylabError, ValueError):
    """A value that must be finite (an observation, a reward, a loss) is NaN or infinite."""


class NotConvergedWarning(UserWarning):
    """An iterative method stopped at its iteration limit before converging."""


class RunFolderError(PolicylabError, ValueError):
    """A run folder cannot be used as asked.

    It is in use by another process, already holds a run (without resume), holds none
    (with resume), or holds a different run.
    """


class TrainingInterrupted(KeyboardInterrupt):
    """Training stopped on Ctrl-C or SIGTERM after saving a checkpoint at step :attr:`step`.

    A ``KeyboardInterrupt``, so code that stops on Ctrl-C stops on it too. ``signal``
    is the signal's number (2 for Ctrl-C's SIGINT, 15 for SIGTERM).
    """

    def __init__(self, step: int, path: str, signal: int = 2) -> None:
        super().__init__(f"interrupted at step {step:,}; the checkpoint is in {path}")
        self.step = step
        self.path = path
        self.signal = signal
