!> Stochastic cell rescaling (Bernetti and Bussi, J. Chem. Phys. 153, 114107 (2020)), isotropic,
!> first order in eps = ln V:
!>   d eps = -(beta_T / tau_p) (P0 - P_int - k T / V) dt + sqrt(2 k T beta_T / (V tau_p)) dW
!> with P_int = (2 K + W) / (d V), the kinetic energy and virial of the end of the previous step.
!> Applied after each step's drift, before its force pass: the box and the positions are scaled
!> by exp(d eps / d), the velocities by exp(-d eps / d). The noise is one normal number per step,
!> drawn from the counter-based generator keyed by (seed, step): the same on every rank. The
!> volume fluctuations are those of the isothermal-isobaric ensemble (unlike Berendsen's).
module terrace_barostat_c_rescale
    use terrace_kinds, only: dp, i8
    use terrace_engine, only: engine_t
    use terrace_barostat, only: barostat_t, barostat_params_t, internal_pressure
    use terrace_counter_rng, only: rng_stream, rng_stream_t
    use terrace_named_values, only: named_values_t
    implicit none
    private

    integer, parameter :: stream_c_rescale = 202   !< the generator's stream for this barostat

    type, extends(barostat_t), public :: c_rescale_t
        real(dp) :: p_int = 0                    !< the internal pressure at the end of the last step
        logical :: have_p = .false.
    contains
        procedure :: needs_virial => cr_needs_virial
        procedure :: before_forces => cr_before_forces
        procedure :: after_step => cr_after_step
        procedure :: save => cr_save
        procedure :: restore => cr_restore
    end type c_rescale_t

contains

    logical function cr_needs_virial(self, step)
        class(c_rescale_t), intent(in) :: self
        integer(i8), intent(in) :: step
        cr_needs_virial = .true.
    end function cr_needs_virial

    subroutine cr_before_forces(self, eng, step, moved)
        class(c_rescale_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        integer(i8), intent(in) :: step
        logical, intent(out) :: moved
        type(rng_stream_t) :: s
        real(dp) :: v, deps, mu
        integer :: d
        if (.not. self%have_p) then          ! the first step: the pressure of the initial state
            self%p_int = internal_pressure(eng)
            self%have_p = .true.
        end if
        v = eng%box%volume()
        s = rng_stream(self%seed, stream_c_rescale, 0_i8, step)
        deps = -(self%beta/self%tau)*(self%p0 - self%p_int - self%kt/v)*self%dt + &
               sqrt(2*self%kt*self%beta*self%dt/(v*self%tau))*s%normal()
        mu = exp(deps/self%dimension)
        call eng%scale_box([(merge(mu, 1.0_dp, d <= self%dimension), d = 1, 3)], velocities=.true.)
        moved = .true.
    end subroutine cr_before_forces

    subroutine cr_after_step(self, eng, step, moved)
        class(c_rescale_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        integer(i8), intent(in) :: step
        logical, intent(out) :: moved
        moved = .false.
        self%p_int = internal_pressure(eng)
        self%have_p = .true.
    end subroutine cr_after_step

    subroutine cr_save(self, values)
        class(c_rescale_t), intent(inout) :: self
        type(named_values_t), intent(inout) :: values
        call values%put('baro_p_int', self%p_int)
    end subroutine cr_save

    subroutine cr_restore(self, values, ok)
        class(c_rescale_t), intent(inout) :: self
        type(named_values_t), intent(in) :: values
        logical, intent(inout) :: ok
        self%p_int = values%get_r('baro_p_int', ok)
        self%have_p = .true.
    end subroutine cr_restore

end module terrace_barostat_c_rescale
