"""MkDocs hook: the package's docstrings use Sphinx cross-reference roles (:class:`X`, :func:`f`, ...);
mkdocstrings renders the backquoted name as code and leaves the role's prefix as text.  Drop the prefix."""
import re

_ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|data|attr|obj|exc|const):(?=<code>|<a )")


def on_page_content(html, page, config, files):
    return _ROLE.sub("", html)
