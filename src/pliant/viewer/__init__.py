"""The browser environment: ``pliant view`` serves the page and one coupled session per
tab over a websocket (``protocol`` defines the messages, ``state`` turns a session into
them, ``server`` carries them)."""
