"""Inference over fitted models: the activity filter, the forecaster and the fetch policy.

The counting models (:mod:`globe.models`) say what comes next from a state; everything here
reasons over many states at once through their state spaces (one beam step for the filter and
the forecaster's paths), the movement evidence and the movement model.
"""
