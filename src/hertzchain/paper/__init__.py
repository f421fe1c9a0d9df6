"""The paper as a virtual experiment (Melo, Job, Santibanez, Tapia, PRE 2006).

- :mod:`.values`: the paper's own numbers (Table I, Q_1, Q_2, eps, ...);
- :mod:`.protocol`: the runs of its measurement protocol and their analysis (data only);
- :mod:`.figures`: one function per paper figure, drawn from that data;
- :mod:`.report`: summary.json, report.md and report.html (:mod:`.notes`: what it says, from the
  numbers; :mod:`.render`: Markdown and HTML);
- :mod:`.reproduce`: the one call behind ``hertzchain reproduce``.
"""
