"""The one exception type that means "the input is wrong", not "the code is wrong".

The command line turns it into one line on stderr and exit status 2; every
package raises it (or a subclass) for impossible parameters and bad files."""


class InputError(ValueError):
    """Bad input from a user: an impossible parameter, a malformed file."""


class SolverError(RuntimeError):
    """A solve that did not converge: the message says why."""
