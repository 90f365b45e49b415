"""``--scheduler ADDRESS``: make sure a Dask scheduler answers there, in bounded time.

``distributed.Client`` waits far longer than its ``timeout`` when the address accepts a
connection but never speaks Dask (a silent listener, an HTTP server), and a scheme it has no
backend for (``ucx://`` without ucx-py) ends in a long traceback. :func:`probe_scheduler`
therefore checks, before any client is made:

1. the address form: ``[tcp://|tls://]HOST:PORT`` with a port in 1..65535;
2. within ``timeout`` seconds in all (connect, Dask handshake, one ``identity`` call): that
   the peer answers ``identity`` as a Dask ``Scheduler``.

Anything else is one :class:`SchedulerUnreachable` line naming the address and what is
allowed.
"""

from __future__ import annotations

import asyncio
import re
from typing import Any

from otmm_qp.exceptions import OtmmError

#: Address schemes accepted for ``--scheduler``.
SCHEMES = ("tcp", "tls")
_ADDRESS = re.compile(
    r"^(?:(?P<scheme>[A-Za-z][A-Za-z0-9+.-]*)://)?(?P<host>[^\s/]+):(?P<port>\d+)$"
)


class SchedulerUnreachable(OtmmError):
    """The Dask scheduler address is malformed, unreachable or not a Dask scheduler."""


def _fail(address: str, reason: str) -> SchedulerUnreachable:
    """``--scheduler: REASON`` with ``{at}`` in ``reason`` replaced by the (cut) address."""
    shown = address if len(address) <= 80 else address[:77] + "..."
    return SchedulerUnreachable("--scheduler: " + reason.replace("{at}", f"at {shown!r}"))


def check_address(address: str) -> str:
    """``address`` with its scheme made explicit (``tcp://`` by default).

    Raises:
        SchedulerUnreachable: Not ``[tcp://|tls://]HOST:PORT`` with a port in 1..65535.
    """
    match = _ADDRESS.match(address.strip())
    if match is None:
        raise _fail(
            address, "cannot use the address {at}: expected tcp://HOST:PORT or tls://HOST:PORT"
        )
    scheme = (match.group("scheme") or "tcp").lower()
    if scheme not in SCHEMES:
        raise _fail(
            address,
            f"cannot use the address {{at}}: scheme {scheme}:// is not supported; "
            "use tcp://HOST:PORT or tls://HOST:PORT",
        )
    port = int(match.group("port"))
    if not 1 <= port <= 65535:
        raise _fail(address, f"cannot use the address {{at}}: port must be in 1..65535, got {port}")
    return f"{scheme}://{match.group('host')}:{port}"


async def _identity(address: str, timeout: float) -> Any:
    from distributed.comm import connect

    comm = await connect(address, timeout=timeout)
    try:
        await comm.write({"op": "identity", "reply": True})
        return await comm.read()
    finally:
        comm.abort()


def probe_scheduler(address: str, timeout: float) -> str:
    """Check that a Dask scheduler answers at ``address`` within ``timeout`` seconds.

    Args:
        address: The ``--scheduler`` value.
        timeout: Bound on the whole check (connect, handshake, identity reply) [s].

    Returns:
        The address with an explicit scheme.

    Raises:
        SchedulerUnreachable: Malformed address, nothing listening, no answer within
            ``timeout``, or an answer that is not a Dask scheduler's.
    """
    full = check_address(address)

    async def bounded() -> Any:
        return await asyncio.wait_for(_identity(full, timeout), timeout)

    try:
        reply = asyncio.run(bounded())
    except (TimeoutError, asyncio.TimeoutError):
        raise _fail(
            address, f"cannot reach a Dask scheduler {{at}}: no answer within {timeout:g} s"
        ) from None
    except Exception as error:  # noqa: BLE001 - any failure of a foreign peer is one line
        name = type(error).__name__
        raise _fail(
            address, f"cannot reach a Dask scheduler {{at}} within {timeout:g} s ({name})"
        ) from None
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise _fail(address, "cannot reach a Dask scheduler {at}: the peer is not a Dask scheduler")
    return full
