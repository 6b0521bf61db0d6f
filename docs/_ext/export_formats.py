"""The docs' table of export formats, made from the export registry
(``fluorogui.workflow.exports.formats()``), so a format added as a module appears here
without editing a page.

Directive::

    .. export-formats::
"""
from __future__ import annotations

from docutils.parsers.rst import Directive
from docutils.statemachine import StringList


class ExportFormats(Directive):
    has_content = False

    def run(self):
        from fluorogui.workflow.exports import formats

        lines = [".. list-table::", "   :header-rows: 1", "   :widths: 14 36 22 28", "",
                 "   * - Option", "     - What", "     - Default name (app)", "     - Needs, holds"]
        for fmt in formats():
            option = f"``--{fmt.name} {fmt.metavar}``" + (" ``--view K``" if fmt.needs_view else "")
            needs = [*(["a frame rate"] if fmt.timed else []), *(["the knee's side"] if fmt.kinematic else []),
                     *(["matched or accepted poses only"] if fmt.motion else []),
                     *(["no flagged poses unless accepted"] if fmt.statusless else [])]
            lines += [f"   * - {option}", f"     - {fmt.label}", f"     - ``{fmt.default_name}``",
                      f"     - {', '.join(needs) or '-'}"]
        node_list = []
        from docutils import nodes

        container = nodes.container()
        self.state.nested_parse(StringList(lines, source="export registry"), self.content_offset, container)
        node_list.extend(container.children)
        return node_list


def setup(app):
    app.add_directive("export-formats", ExportFormats)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
