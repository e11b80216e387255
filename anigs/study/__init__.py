"""The paper's 2AFC user study (Table 4): build a study page, serve it, tally the answers.

- :mod:`anigs.study.schema`: the answer record and its check;
- :mod:`anigs.study.build`: study folder (HTML + JS + videos) from the final videos;
- :mod:`anigs.study.serve`: local server that collects posted answers in a JSONL file;
- :mod:`anigs.study.stats`: binomial intervals and the exact test;
- :mod:`anigs.study.tally`: answer files -> Table 4 (CSV, Markdown, LaTeX) with exclusions;
- the command ``anigs study {build,serve,tally}``: :mod:`anigs.stages.study` (it finds the final stage's folders).
"""
