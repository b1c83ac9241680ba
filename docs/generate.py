"""Rewrite docs/reference/ and docs/schemas/ from orchestrator/languages.py.

    .venv/bin/python docs/generate.py

tests/orchestrator/test_languages.py fails while the committed files differ from
what this writes, so run it after changing a parser's keys (and languages.py).
"""

from pathlib import Path

from gyrocal.app.reference_docs import write_documents

if __name__ == "__main__":
    for path in write_documents(Path(__file__).resolve().parent.parent):
        print(path)
