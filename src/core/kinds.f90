!> Numeric kinds used throughout Terrace.
module terrace_kinds
    use, intrinsic :: iso_fortran_env, only: real64, int64
    implicit none
    private
    integer, parameter, public :: dp = real64   !< all floating-point state
    integer, parameter, public :: i8 = int64    !< global atom ids, step counters
    real(dp), parameter, public :: pi = acos(-1.0_dp)
end module terrace_kinds
