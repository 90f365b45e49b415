"""Peer IK libraries as backends in the same loop: pink, mink (MuJoCo), Drake and OInK.

Installed with ``pip install "otmm-qp[peers]"`` and registered as the ``pink``, ``mink``,
``drake`` and ``oink`` entry points of ``otmm_qp.backends``. The adapters import their library
only when constructed, so a missing peer raises :class:`~otmm_qp.exceptions.PeerUnavailable` (the
runner reports the controller as skipped with the install hint) and never breaks the rest.
"""

from .drake_backend import DrakeBackend
from .mink_backend import MinkBackend
from .oink_backend import OinkBackend
from .peer_backend import INSTALL_HINTS, PeerBackend, require
from .pink_backend import PinkBackend

__all__ = [
    "INSTALL_HINTS",
    "DrakeBackend",
    "MinkBackend",
    "OinkBackend",
    "PeerBackend",
    "PinkBackend",
    "require",
]
