"""The notebooks' own helpers, at the top of the library: :func:`.setup.setup_notebook` (the one
call at the top of every notebook) and :mod:`.runner` (executes notebooks headless into
``build/``)."""
