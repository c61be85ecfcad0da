"""Opcodes of the tape (shared by the host compiler and the device interpreters).

An instruction is ``(op, dst, a, b)`` plus one float immediate ``imm``; ``a``/``b`` are
register numbers (``-1`` when unused). Plain ints here; kernel modules wrap them with
``wp.constant``. ``NAMES`` maps every opcode (``0 .. N_OPS - 1``) to its name.
"""

X = 0  # dst = x
Y = 1  # dst = y
Z = 2  # dst = z
CONST = 3  # dst = imm
ADD = 4  # dst = a + b
SUB = 5  # dst = a - b
MUL = 6  # dst = a * b
DIV = 7  # dst = a / b
MIN = 8  # dst = min(a, b)
MAX = 9  # dst = max(a, b)
ADDC = 10  # dst = a + imm
MULC = 11  # dst = a * imm
RSUBC = 12  # dst = imm - a
RDIVC = 13  # dst = imm / a
MINC = 14  # dst = min(a, imm)
MAXC = 15  # dst = max(a, imm)
NEG = 16  # dst = -a
ABS = 17  # dst = |a|
SQUARE = 18  # dst = a * a
SQRT = 19  # dst = sqrt(max(a, 0))
SIN = 20
COS = 21
EXP = 22
LOG = 23  # dst = log(a) (a > 0)
POWI = 24  # dst = a ** imm, imm an integer
POWF = 25  # dst = |a| ** imm (non-integer exponent: the sign of a is dropped)
RUNION = 26  # dst = a + b + sqrt(a^2 + b^2)   (R-function union, [FG eq. 16.17])
RINTER = 27  # dst = a + b - sqrt(a^2 + b^2)   (R-function intersection)
COPY = 28  # dst = a  (made only by tape pruning, warpmesh.frep.prune: a min/max decided over a cell)

N_OPS = 29

#: opcodes that no expression compiles to: they appear only in pruned tapes
PRUNE_ONLY = frozenset({COPY})

NAMES = {v: k for k, v in dict(globals()).items() if isinstance(v, int) and k.isupper() and k != "N_OPS"}
