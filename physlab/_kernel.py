"""A notebook kernel client that never sleeps through a message that is already there.

``nbclient.NotebookClient`` waits for a cell's reply with a single ``poll(timeout)`` on an
asyncio zmq socket. On the 2-core CI hosts that wait sometimes misses the socket's wake-up
(a zmq socket's file descriptor is edge-triggered): the kernel's reply is queued, yet the
client sleeps until the whole cell timeout has passed and only then finds it, because
pyzmq's poller ends a timed-out wait with one last ``poll(0)``. The cell then "passes"
late. Measured on 2026-11-28 with a two-cell widget notebook and the kernel's streams
captured by pytest: 62 s with a 60 s cell timeout instead of 4 s (the record of the
kernel's own timestamps shows the reply 2 s after the request), and a 604 s wait of
``physlab reproduce`` under its 600 s timeout.

:class:`PatientChannel` waits in slices of at most :attr:`PatientChannel.slice_seconds`, so a
missed wake-up costs at most one slice; timeouts keep their meaning (``Empty`` is raised
only when the caller's whole timeout has passed). :func:`notebook_client` builds an
``NotebookClient`` whose kernel manager hands out such clients for the shell and IOPub
channels. This module imports jupyter_client at the top: import it lazily.
"""
from __future__ import annotations

import time
from queue import Empty

from jupyter_client.asynchronous import AsyncKernelClient
from jupyter_client.channels import AsyncZMQSocketChannel
from jupyter_client.manager import AsyncKernelManager
from traitlets import DottedObjectName, Type


class PatientChannel(AsyncZMQSocketChannel):
    """``get_msg`` that re-polls the socket every ``slice_seconds`` until ``timeout``."""

    slice_seconds = 1.0

    async def get_msg(self, timeout: float | None = None) -> dict:
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            wait = self.slice_seconds
            if deadline is not None:
                wait = min(wait, max(0.0, deadline - time.monotonic()))
            try:
                return await super().get_msg(timeout=wait)
            except Empty:
                if deadline is not None and time.monotonic() >= deadline:
                    raise


class PatientKernelClient(AsyncKernelClient):
    """An ``AsyncKernelClient`` whose shell and IOPub channels are :class:`PatientChannel`."""

    shell_channel_class = Type(PatientChannel)
    iopub_channel_class = Type(PatientChannel)


class PatientKernelManager(AsyncKernelManager):
    """An ``AsyncKernelManager`` whose clients are :class:`PatientKernelClient`."""

    client_factory = Type(PatientKernelClient, klass=AsyncKernelClient, config=True)
    # (what client() builds is client_factory; the dotted name is kept in step with it)
    client_class = DottedObjectName(f"{__name__}.{PatientKernelClient.__qualname__}",
                                    config=True)


def notebook_client(nb, **kwargs):
    """``nbclient.NotebookClient(nb, **kwargs)`` with :class:`PatientKernelManager`."""
    from nbclient import NotebookClient

    return NotebookClient(nb, kernel_manager_class=PatientKernelManager, **kwargs)
