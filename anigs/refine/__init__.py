"""The refine stage's method: ComposedV2V (compose.py) with the video priors (prior/: the
procedural spectral motion offline, LTX-Video with local weights).
"""
