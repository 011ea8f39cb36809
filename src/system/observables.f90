!> Observables of the whole system at one instant, as the integrators sample them:
!>   temp = 2 KE / (N_f k_B) (N_f = D N - D), etotal = pe + ke, press = (2 KE + W) / (D V) (W the
!>   virial sum r_ij . f_ij, D the dimension),
!>   momentum = sum_i m_i v_i, angular = sum_i m_i r_i x v_i (unwrapped positions, about the origin).
!> Writers (thermo CSV, trajectory observables) and checks (drift, momentum) take a sample; none
!> of them computes it.
module terrace_observables
    use terrace_kinds, only: dp, i8
    implicit none
    private

    type, public :: thermo_sample_t
        integer(i8) :: step = 0
        real(dp) :: time = 0, temp = 0, pe = 0, ke = 0, etotal = 0, press = 0
        real(dp) :: momentum(3) = 0      !< total linear momentum (mass x velocity units)
        real(dp) :: ecouple = 0          !< energy put in by the thermostat so far (0 without one)
        real(dp) :: angular(3) = 0       !< total angular momentum about the origin (unwrapped positions)
    end type thermo_sample_t

end module terrace_observables
