"""ABB computer link: ``framing`` (DLE STX ... DLE ETX + check, DLE ACK/NAK/ENQ), ``messages``."""
