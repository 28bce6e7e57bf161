"""DQN family: Double DQN, dueling heads, n-step returns, prioritized replay."""

from policylab.deep.dqn.agent import DQN, DQNConfig
from policylab.deep.dqn.losses import q_learning_targets, td_loss
from policylab.deep.dqn.networks import QNetwork

__all__ = ["DQN", "DQNConfig", "QNetwork", "q_learning_targets", "td_loss"]
