!> Unit systems (LAMMPS conventions, so that results compare with LAMMPS to round-off).
!>
!> metal: energy eV, length Angstrom, time ps, mass amu (g/mol), temperature K, pressure bar.
!> lj:    reduced units, every conversion factor is 1.
!> si:    energy J, length m, time s, mass kg, temperature K, pressure Pa (elastic solids): every
!>        conversion factor is 1, k_B = 1.380649e-23 J/K (exact since 2019).
!>
!> Kinetic energy     KE = mvv2e * sum m v^2 / 2
!> Acceleration        a = ftm2v * f / m
!> Pressure            p = nktv2p * (2 KE + W) / (d V),  W = sum over pairs r . f
module terrace_units
    use terrace_kinds, only: dp
    implicit none
    private

    type, public :: units_t
        character(len=8) :: name = 'metal'
        real(dp) :: boltz = 8.617343e-5_dp     !< k_B in energy units per K
        real(dp) :: mvv2e = 1.0364269e-4_dp    !< mass*velocity^2 -> energy
        real(dp) :: ftm2v = 1.0_dp/1.0364269e-4_dp  !< force/mass*time -> velocity
        real(dp) :: nktv2p = 1.6021765e6_dp    !< energy/volume -> pressure
        character(len=16) :: energy = 'eV', length = 'Angstrom', time = 'ps', mass = 'amu', &
                             temperature = 'K', pressure = 'bar', velocity = 'Angstrom/ps'
        ! defaults where the deck gives none: the time step, the neighbour list's skin, and the bulk
        ! modulus (energy/volume) of a box relaxation's first volume step
        real(dp) :: default_dt = 0.001_dp, default_skin = 2.0_dp, bulk_modulus_guess = 1.0_dp
    end type units_t

    public :: make_units, unit_names_allowed

    character(len=*), parameter :: unit_names_allowed = "'metal', 'lj', 'si'"

contains

    !> Build the unit system called `name`; ok is false for an unknown name.
    function make_units(name, ok) result(u)
        character(len=*), intent(in) :: name
        logical, intent(out) :: ok
        type(units_t) :: u
        ok = .true.
        select case (trim(name))
        case ('metal')
            u = units_t()
        case ('lj')
            u%name = 'lj'
            u%boltz = 1.0_dp; u%mvv2e = 1.0_dp; u%ftm2v = 1.0_dp; u%nktv2p = 1.0_dp
            u%energy = 'epsilon'; u%length = 'sigma'; u%time = 'tau'; u%mass = 'm'
            u%temperature = 'epsilon/k_B'; u%pressure = 'epsilon/sigma^3'; u%velocity = 'sigma/tau'
            u%default_dt = 0.005_dp; u%default_skin = 0.3_dp; u%bulk_modulus_guess = 100.0_dp
        case ('si')
            u%name = 'si'
            u%boltz = 1.380649e-23_dp; u%mvv2e = 1.0_dp; u%ftm2v = 1.0_dp; u%nktv2p = 1.0_dp
            u%energy = 'J'; u%length = 'm'; u%time = 's'; u%mass = 'kg'
            u%temperature = 'K'; u%pressure = 'Pa'; u%velocity = 'm/s'
            u%bulk_modulus_guess = 1.0e11_dp
        case default
            ok = .false.
        end select
    end function make_units

end module terrace_units
