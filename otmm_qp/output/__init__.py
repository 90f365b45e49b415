"""Outputs: summaries, claims verdicts, figures and the comparison report."""
