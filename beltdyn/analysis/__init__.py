"""The analyses on a `System`: static (and the solved-geometry passes), modal, running belt,
transient (the stepper and its parts), steady response, the fidelity ladder, time-step accuracy,
spectra. See docs/architecture.md.
"""
