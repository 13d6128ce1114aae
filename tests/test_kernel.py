"""physlab._kernel: the notebook kernel client that never sleeps through a ready message."""
import asyncio
import time
from queue import Empty

import pytest
import zmq
import zmq.asyncio
from jupyter_client.channels import AsyncZMQSocketChannel
from jupyter_client.session import Session

from physlab._kernel import PatientChannel, PatientKernelClient, notebook_client


async def _reply_after_a_missed_wakeup(channel_class, timeout, slice_seconds=None):
    """Start ``get_msg(timeout)``, then deliver a reply whose wake-up the event loop misses.

    A zmq socket's file descriptor is edge-triggered: whoever processes the socket's
    pending commands first (here a plain ``poll`` on a shadow of the socket, in the CI
    hang an unknown one) consumes the signal, and the asyncio poller is never woken.
    Returns the message and the seconds from delivery to ``get_msg`` returning."""
    ctx, sync_ctx = zmq.asyncio.Context(), zmq.Context()
    kernel_side = sync_ctx.socket(zmq.PAIR)
    client_side = ctx.socket(zmq.PAIR)
    port = client_side.bind_to_random_port("tcp://127.0.0.1")
    kernel_side.connect(f"tcp://127.0.0.1:{port}")
    try:
        session = Session(key=b"")
        channel = channel_class(client_side, session)
        if slice_seconds is not None:
            channel.slice_seconds = slice_seconds
        waiting = asyncio.ensure_future(channel.get_msg(timeout=timeout))
        for _ in range(5):                      # the poll is registered and idle
            await asyncio.sleep(0.01)
        session.send(kernel_side, "execute_reply", {"status": "ok"})
        shadow = zmq.Socket.shadow(client_side.underlying)
        assert shadow.poll(5000) == zmq.POLLIN  # the reply is queued; its signal is consumed
        t0 = time.perf_counter()
        msg = await asyncio.wait_for(waiting, 20)
        return msg, time.perf_counter() - t0
    finally:
        kernel_side.close(0)
        client_side.close(0)
        ctx.term()
        sync_ctx.term()


def test_the_plain_channel_sleeps_through_a_missed_wakeup_until_its_timeout():
    """The failure that stalled CI (604 s under a 600 s cell timeout), reproduced: the
    message is there all along, and jupyter_client's channel finds it only at the end."""
    msg, waited = asyncio.run(_reply_after_a_missed_wakeup(AsyncZMQSocketChannel, timeout=3))
    assert msg["msg_type"] == "execute_reply" and msg["content"] == {"status": "ok"}
    assert waited > 2.0


def test_a_missed_wakeup_costs_the_patient_channel_one_slice_not_the_timeout():
    msg, waited = asyncio.run(
        _reply_after_a_missed_wakeup(PatientChannel, timeout=600, slice_seconds=0.05))
    assert msg["msg_type"] == "execute_reply" and msg["content"] == {"status": "ok"}
    assert waited < 15                          # (wait_for above fails at 20 s; the plain: 600 s)


def test_the_patient_channel_raises_empty_only_after_the_whole_timeout():
    async def wait_for_nothing():
        ctx = zmq.asyncio.Context()
        sock = ctx.socket(zmq.PAIR)
        sock.bind_to_random_port("tcp://127.0.0.1")
        channel = PatientChannel(sock, Session(key=b""))
        channel.slice_seconds = 0.05
        t0 = time.perf_counter()
        try:
            with pytest.raises(Empty):
                await channel.get_msg(timeout=0.4)
            return time.perf_counter() - t0
        finally:
            sock.close(0)
            ctx.term()

    assert asyncio.run(wait_for_nothing()) >= 0.4


def test_notebook_clients_get_patient_shell_and_iopub_channels():
    from nbformat.v4 import new_notebook

    client = notebook_client(new_notebook(), timeout=5, kernel_name="python3")
    km = client.kernel_manager_class(kernel_name="python3")
    kc = km.client()
    assert isinstance(kc, PatientKernelClient)
    assert kc.shell_channel_class is PatientChannel and kc.iopub_channel_class is PatientChannel
    assert client.timeout == 5                  # NotebookClient's own options pass through
