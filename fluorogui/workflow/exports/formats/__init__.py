"""The export formats, one module each; importing a module registers its format
(``exports.registry.formats()`` imports them all). Adding a format is adding a module here."""
