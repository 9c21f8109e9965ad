"""Every command in README.md and docs/*.md is run (issue 24): test_docs_commands.py holds the table and tests.

Every fenced block of the README and of docs/*.md is either commands (``sh``, ``python``) or not (``text``,
``json``, ``ini``: a tree, an output listing, a body). Every command of a command block is in ``COMMANDS``: run,
with a check of what it answers, or exempt with the reason it cannot run in a test. A command in neither, or an
entry whose command is gone, fails ``test_every_command_is_run_or_exempt``.

The commands run as written, each in a fresh directory (holding what the earlier commands of its block that it
``needs`` wrote), with these changes only:

- ``localhost:8000`` (or ``127.0.0.1:8000``) is one ``vibfree serve`` (tests/app/server.py) on a free port, with
  one HTTP process and one solver worker (warm in ~13 s; the documented two processes take ~35 s here);
- ``vibfree``, ``python``, ``python3`` and ``.venv/bin/`` are this environment's, importing this checkout;
- only what ``make serve`` (``pip install .``) installs can be imported, plus the extras the command's own text
  names (a ``sitecustomize`` hides the other installed packages): a snippet that imports pandas fails;
- curl writes each answer's status and media type on stderr (a ``.curlrc`` in ``CURL_HOME``);
- the files the docs describe in prose are there: ``request.json`` (the example below the command-line block),
  ``sweep.json`` (docs/sweeps.md's body, with 3 points and 1 refined: its 82 time-optimal designs take 48 s),
  ``record.csv`` (docs/identification.md's record), and ``mkdocs.yml`` with ``docs/`` for the site's commands.

The commands run three at a time while the server warms up (those marked ``exclusive``, which fill its queues,
one at a time); identical blocks (the README repeats some of docs/) and identical commands run once. Most of their
time is the service's import, ~4 s of CPU per command that designs in-process.

The modules: ``extract`` finds the blocks and their commands, ``documented`` reads the inputs and answers the docs
describe, ``sandbox`` runs the commands (what they may import, the server, the runner), ``checks`` checks what they
answer, and ``test_docs_commands`` holds ``COMMANDS`` and the tests.
"""
