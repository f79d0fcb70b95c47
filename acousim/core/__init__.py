"""What every stage shares, below all of them: the air (:mod:`.air`), the materials'
frequency-dependent reflection (:mod:`.materials`), the echoes a renderer takes
(:mod:`.echoes`) and the names of the render's settings: interpolators, rate,
compression (:mod:`.rendering`); work shared with a forked process (:mod:`.forked`).
Imports nothing of acousim (see docs/architecture.md)."""
