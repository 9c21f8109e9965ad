"""The smoother family (Biagiotti): harmonic and damped-harmonic smoothers, their discrete filters and tuning, and
the adapter (family.py)."""
