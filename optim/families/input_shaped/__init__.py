"""The input-shaping family (Chatlatanagulchai & Pongpanich): the shapers under an acceleration limit, their
baselines, the firmware settings, and the adapter (family.py)."""
