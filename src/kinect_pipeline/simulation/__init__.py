"""Synthetic data with exact ground truth: scenes rendered by the core (:mod:`.scenes`), the simulated Segway
(:mod:`.robot`) and sequences of it written as bags (:mod:`.sequence_bag`)."""
