"""The capture stage's library: its config (:mod:`anigs.capture.config`). The synthetic capture
itself is :mod:`anigs.synth.capture`, the photo import :mod:`anigs.photos`."""
