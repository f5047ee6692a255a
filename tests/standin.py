"""Stand-ins for Snakemake's objects, for running scripts and adapters without Snakemake."""


class Names(list):
    """A list whose named items are also attributes, like Snakemake's namedlist."""

    def __init__(self, items=(), **named):
        super().__init__(list(items) + list(named.values()))
        self._named = named
        for k, v in named.items():
            setattr(self, k, v)

    def items(self):
        return self._named.items()

    def keys(self):
        return self._named.keys()

    def __getitem__(self, key):
        return self._named[key] if isinstance(key, str) else super().__getitem__(key)
