"""Measuring the pipeline's output against ground truth: one frame (:mod:`.metrics`), the quality tables
(:mod:`.quality`), negative obstacles (:mod:`.cliff`), the golden outputs (:mod:`.regress`) and the report of a replay
(:mod:`.report`)."""
