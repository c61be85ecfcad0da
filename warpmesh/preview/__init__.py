"""Real-time preview: parameter edits re-meshed in an edit loop, shown off-screen, in HTML and in notebooks.

``session`` (:class:`~warpmesh.preview.session.Preview`: the edit loop), ``render`` (PNG
through pyvista off-screen, the self-contained WebGL page, the notebook mime bundle),
``viewer`` (the WebGL viewer's JavaScript), ``widget`` (the Jupyter widget: sliders and
the viewer, through anywidget), ``instrument`` (counting Warp module loads).
"""
