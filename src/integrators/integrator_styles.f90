!> The &integrator styles as data: each style's name, the &integrator keys of its own and how it
!> advances time: by a fixed time step (velocity Verlet), from event to event on straight lines
!> with the times exact (energy stepping), or from collision to collision (event-driven dynamics
!> of stepped potentials). The deck reader and the run's assembly decide through these records and
!> never compare a style name. Adding an integrator: one row in `integrator_table`.
module terrace_integrator_styles
    implicit none
    private

    !> What one &integrator style is and takes.
    type, public :: integrator_style_t
        character(len=24) :: name = ''              !< '' for a name no style has
        !> its own keys, separated by blanks (style is every style's)
        character(len=64) :: keys = ''
        logical :: time_stepped = .false.           !< a fixed time step dt; outputs counted in steps
        !> between events atoms move on straight lines, forces act as jumps, outputs at exact times:
        !> needs a continuous potential in double precision, the exact neighbour list (skin > 0) and
        !> thermostats that act at events
        logical :: exact_time = .false.
        logical :: event_driven = .false.           !< pair events of stepped potentials, no time step
        logical :: smooth_potentials = .false.      !< runs potentials with continuous forces
        logical :: stepped_potentials = .false.     !< runs stepped potentials (impulses at the steps)
        !> what --check prints after its name when it has no time step
        character(len=80) :: plan_note = ''
    end type integrator_style_t

    !> Every style, in the order the messages list them; row 0 stands for a name no style has.
    type(integrator_style_t), parameter, public :: integrator_table(0:3) = [integrator_style_t(), &
        integrator_style_t('velocity_verlet', 'dt', time_stepped=.true., smooth_potentials=.true.), &
        integrator_style_t('energy_stepping', 'terrace_height target_mean_dt root_tolerance', exact_time=.true., &
                           smooth_potentials=.true., &
                           plan_note='no time step: the next event decides; terrace height below'), &
        integrator_style_t('event_driven', '', event_driven=.true., stepped_potentials=.true., &
                           plan_note='no time step: exact pair and cell-crossing events, outputs at exact times')]

    !> The style of a deck without &integrator style.
    character(len=*), parameter, public :: default_integrator_style = 'velocity_verlet'

end module terrace_integrator_styles
