"""Config schema versions: the table of changes of meaning and the checks and migrations on it.

A leaf package (it imports only :mod:`otmm_qp.exceptions`), so the registry and the config
loader can both consult it without an import cycle.
"""
