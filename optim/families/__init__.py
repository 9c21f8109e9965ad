"""The families' adapters, one module each, between the pipeline and each family's synthesis; the registry of
them is optim.registry."""
