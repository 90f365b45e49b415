"""YAML experiment configs shipped with otmm-qp (the embedded paper default lives here)."""
