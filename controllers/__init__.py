"""Built-in backends of otmm-qp, registered through ``otmm_qp.backends`` entry points.

This package is installed as ``otmm_qp_controllers`` and registered exactly the way a
third-party plugin package registers its own backends (see ``pyproject.toml``).
"""
