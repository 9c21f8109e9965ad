"""Identification: a mode from a free vibration (free_vibration, Biagiotti eq. 16), modes from a measured record
(modal), and the record CSV parser (record_csv)."""
