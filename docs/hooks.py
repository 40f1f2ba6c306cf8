"""mkdocs hook: the docstrings' reStructuredText roles (:class:`~a.b.C`, :func:`f`) as plain code in the
API reference, which mkdocstrings renders as Markdown (``code`` is already code there)."""
import re

_ROLE = re.compile(r":(?:class|func|meth|mod|attr|data|exc|obj):<code>(~?)([^<]+)</code>")


def on_page_content(html, **kwargs):
    return _ROLE.sub(lambda m: f"<code>{m.group(2).rsplit('.', 1)[-1] if m.group(1) else m.group(2)}</code>", html)
