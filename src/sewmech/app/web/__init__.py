"""The interactive page (``sewmech serve``): :mod:`.session` computes what the page shows from
the library's own calls, :mod:`.server` is the web application around it, ``static/`` holds
the page itself (plain HTML, JavaScript and CSS, drawn on canvases; no build step)."""
