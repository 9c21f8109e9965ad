"""One folder per design family: its method, its typed design block (report.py) and its adapter to the pipeline
(family.py); the registry of them is optim.registry."""
