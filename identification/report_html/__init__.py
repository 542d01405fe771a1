"""Self-contained HTML reports (plotly inlined, opened from disk without a network): a summary first, details
folded. ``page`` is the page skeleton, ``identify_page`` the calibrated model's page, ``diagnosis_page`` the
diagnosis' page. Nothing here prints; the command line decides where a page is written.
"""
