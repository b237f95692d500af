"""A valve model described as plain data: the spec and its TOML file (:mod:`.spec`), the package's own
models as specs (:mod:`.presets`), and a model named by preset or file (:mod:`.modelfile`).
"""
