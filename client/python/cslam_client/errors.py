"""Typed errors of the cslam Python client.

Every error the server sends carries a code (``cslam.wire.ErrorCode``); :class:`ServerError`
keeps it as ``code`` (the number) and ``code_name`` (e.g. ``"ERROR_BAD_HELLO"``), with the
frame's ``seq`` (0 when the error is not about a frame) and the server's message.
"""


class CslamError(Exception):
    """Base class of every error raised by cslam_client."""


class ConnectionFailed(CslamError):
    """The server did not answer in time (no welcome, or silent after every reconnect)."""


class ServerError(CslamError):
    """An Error message from the server."""

    def __init__(self, code, code_name, message, seq=0, client_id=None):
        super().__init__(f"server error {code_name} (seq {seq}): {message}")
        self.code = code
        self.code_name = code_name
        self.server_message = message
        self.seq = seq
        self.client_id = client_id


class ProtocolVersionError(ServerError):
    """The server speaks another protocol version (ERROR_BAD_VERSION)."""


class HelloRejected(ServerError):
    """The server refused the hello: invalid camera or client id (ERROR_BAD_HELLO)."""


class ServerShuttingDown(ServerError):
    """The server is shutting down (ERROR_SHUTTING_DOWN)."""


class TooManyClients(ServerError):
    """The server has --max-clients sessions open (ERROR_TOO_MANY_CLIENTS)."""


class NotAuthorized(ServerError):
    """This connection's CURVE key may not speak for the client id (ERROR_NOT_AUTHORIZED)."""


class SessionBusy(ServerError):
    """The session is live on another connection (ERROR_SESSION_BUSY); connect() retries the hello."""


class FrameRejected(ServerError):
    """Any other server error, e.g. one dropped frame (corrupt image, size mismatch, duplicate seq).

    Not fatal: a dropped frame's credit comes back with the error. A frame's error is raised only
    with ``strict=True``; otherwise counted in ``FrameSender.stats.errors`` (and
    ``stats.frames_refused``) as the C++ FrameSender does.
    """


# Error codes with their own class (the rest are FrameRejected), as client/frame_sender.cpp
# treats them. Looked up by name: codes the wire schema does not have yet are simply absent.
FATAL = {
    "ERROR_BAD_VERSION": ProtocolVersionError,
    "ERROR_BAD_HELLO": HelloRejected,
    "ERROR_SHUTTING_DOWN": ServerShuttingDown,
    "ERROR_TOO_MANY_CLIENTS": TooManyClients,
    "ERROR_NOT_AUTHORIZED": NotAuthorized,  # fatal for a hello; a refused frame is counted
    "ERROR_SESSION_BUSY": SessionBusy,
}


def from_wire(error, pb):
    """The typed exception for a cslam.wire.Error message."""
    name = pb.ErrorCode.Name(error.code) if error.code in pb.ErrorCode.values() else f"ERROR_{error.code}"
    cls = FATAL.get(name, FrameRejected)
    return cls(error.code, name, error.message, error.seq, error.client_id)
