"""Starting or joining Ray: an embedded local Ray, or a running cluster at an address.

Sweeps (:mod:`policylab.experiments`) and AlphaZero's self-play on Ray
(:mod:`policylab.games.alphazero`) both start or join Ray here. Without an address,
:func:`connect` starts a local Ray inside the process, sized to the machine (or to
``num_cpus``), without its dashboard and without usage statistics. With an address it
joins a running cluster (``ray start --head`` on one node, ``ray start
--address=HEAD:6379`` on the others); the address is probed first with a short socket
timeout, so a wrong or unreachable one is refused within seconds instead of hanging.
Ray is imported only when one of these functions needs it.
"""

from __future__ import annotations

import logging
import os
import socket
from types import ModuleType

from policylab.exceptions import InvalidArgumentError

__all__ = ["connect", "import_ray", "parse_address", "probe_address"]

#: Seconds an address probe waits for a TCP connection.
PROBE_TIMEOUT = 3.0


def _quiet_ray_env() -> None:
    """No usage statistics, no Tune banners, no de-duplicated logs: set before importing Ray."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")
    os.environ.setdefault("TUNE_WARN_EXCESSIVE_EXPERIMENT_CHECKPOINT_SYNC_THRESHOLD_S", "0")
    os.environ.setdefault("RAY_DEDUP_LOGS", "0")


def import_ray(what: str = "this") -> ModuleType:
    """The ``ray`` module, imported on first use.

    Args:
        what: What needs Ray, for the message (``"backend=ray"``).

    Raises:
        InvalidArgumentError: Ray is not installed (it comes with the ``sweep`` extra).
    """
    _quiet_ray_env()
    try:
        import ray
    except ImportError:
        raise InvalidArgumentError(
            f"{what} needs Ray, which is not installed: pip install 'policylab[sweep]'"
        ) from None
    return ray


def parse_address(address: str, option: str = "--address") -> tuple[str, int] | None:
    """``(host, port)`` of a cluster address (``HOST:PORT``, ``ray://HOST:PORT``); None for auto.

    Args:
        address: The address.
        option: Where the address was given, for the message.

    Raises:
        InvalidArgumentError: An address without a host or with a bad port.
    """
    text = address.strip()
    if text == "auto":
        return None
    client = text.startswith("ray://")
    rest = text[len("ray://") :] if client else text
    host, colon, port_text = rest.rpartition(":")
    if not colon:
        host, port_text = rest, "10001" if client else "6379"
    try:
        port = int(port_text)
    except ValueError:
        port = -1
    if not host or not 0 < port < 65536:
        raise InvalidArgumentError(
            f"{option} must be HOST:PORT (the head node's `ray start --head` address, port "
            f"6379 by default), ray://HOST:PORT or auto; got {address!r}"
        )
    return host, port


def probe_address(address: str, timeout: float = PROBE_TIMEOUT, option: str = "--address") -> None:
    """Refuse, within ``timeout`` seconds, a cluster address nothing listens on.

    Args:
        address: The address.
        timeout: Seconds to wait for a TCP connection.
        option: Where the address was given, for the message.

    Raises:
        InvalidArgumentError: The address is malformed or cannot be reached.
    """
    hp = parse_address(address, option)
    if hp is None:
        return
    try:
        with socket.create_connection(hp, timeout=timeout):
            pass
    except OSError as e:
        reason = "timed out" if isinstance(e, TimeoutError) else (e.strerror or str(e))
        raise InvalidArgumentError(
            f"cannot reach a Ray cluster at {address!r} ({reason} after at most {timeout:g} s); "
            "start one with `ray start --head` on the head node and pass its address, or "
            f"leave out {option} to run on this machine"
        ) from None


def connect(
    address: str | None = None,
    num_cpus: int | None = None,
    *,
    option: str = "--address",
    what: str = "sweeps and tuning",
) -> bool:
    """Make sure this process is connected to Ray; returns whether this call connected it.

    A process already connected (``ray.init`` called before, as a test or a notebook
    does) is left as it is.

    Args:
        address: A running cluster's address (``HOST:PORT``, ``ray://HOST:PORT`` or
            ``auto``), or None for an embedded local Ray.
        num_cpus: CPUs of the local Ray (default: the machine's).
        option: Where the address was given, for the messages.
        what: What runs on Ray, for the message if Ray is missing.

    Raises:
        InvalidArgumentError: An unreachable or malformed address, or Ray not installed.
    """
    _quiet_ray_env()
    if address is not None:
        probe_address(address, option=option)
        # something that accepts TCP but is no Ray head is given up on within seconds
        os.environ.setdefault("RAY_gcs_rpc_server_connect_timeout_s", "5")
        os.environ.setdefault("RAY_gcs_rpc_server_reconnect_timeout_s", "5")
    ray = import_ray(what)
    logging.getLogger("ray.tune").setLevel(logging.WARNING)  # no "wrote the result files" lines
    if ray.is_initialized():
        return False
    kwargs = {"log_to_driver": False, "logging_level": logging.WARNING, "configure_logging": True}
    try:
        if address is not None:
            ray.init(address=address, **kwargs)
        else:
            # "local": always a fresh Ray in this process, even where RAY_ADDRESS or an
            # earlier `ray start` on this machine would make ray.init join that one
            ray.init(address="local", num_cpus=num_cpus, include_dashboard=False, **kwargs)
    except ConnectionError as e:
        raise InvalidArgumentError(
            f"cannot join the Ray cluster at {address!r}: {' '.join(str(e).split())}"
        ) from None
    return True
