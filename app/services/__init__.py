"""The use cases, one module each, between the routes (HTTP only) and the pipeline (optim): ``profile`` (a family
endpoint's design), ``compare``, ``identify`` (with ``recommend``, its recommended design), ``sweeps``,
``simulate`` and ``shapers`` (the catalogue). The Python API (vibfree.api) calls them too."""
