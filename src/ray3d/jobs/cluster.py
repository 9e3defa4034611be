"""Where a job runs when it runs on Ray: a local Ray started for it (and stopped after it), or a cluster already
running (``auto``, ``ray://HOST:PORT``). Batch jobs and live jobs start it the same way."""

from __future__ import annotations

import logging
import os

from ray3d.errors import InputError

LOCAL = "local"  # the address that asks for a local Ray started for the job


def start_ray(address: str | None, workers: int | None = None, what: str = "batch jobs"):
    """Ray, initialised: on ``address`` (a running cluster), or without one (or ``"local"``) a local Ray with
    ``workers`` CPUs (default: every CPU). Returns the ``ray`` module and whether this call started it (then the
    caller shuts it down)."""
    try:
        import ray
    except ImportError:
        raise InputError(f"{what} run on Ray: pip install 'ray3d[cluster]'") from None
    if ray.is_initialized():
        return ray, False
    if address and address != LOCAL:
        try:
            ray.init(address=address, log_to_driver=False, logging_level=logging.WARNING)
        except (ConnectionError, RuntimeError, ValueError) as err:
            raise InputError(f"address: no Ray cluster at {address} ({str(err).splitlines()[0]})",
                             ("address",)) from None
    else:
        ray.init(num_cpus=workers or os.cpu_count(), include_dashboard=False, log_to_driver=False,
                 logging_level=logging.WARNING)
    return ray, True
