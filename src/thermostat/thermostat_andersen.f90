!> Andersen: each atom's velocity is replaced by a Maxwell-Boltzmann one at rate 1/damping, at the
!> points of a Poisson process per atom; with velocity Verlet in the step whose span holds a point
!> (probability 1 - exp(-dt/damping)), with energy stepping at the exact collision times (calendar
!> events). The global variant (energy stepping with `interval`): every atom's velocity resampled
!> at the multiples of interval.
!>
!> Collision times are a stateless function of (seed, id, time): time is cut into slots of width
!> `damping`; in slot k the atom's collisions are at k damping + damping (E_1 + ... + E_j) for the
!> partial sums below one, E_i exponential draws keyed by (id, k). The slots' points together are a
!> Poisson process of rate 1/damping (independent increments), and the next collision after t is
!> found from (id, t) alone, so nothing per atom needs to go into a checkpoint. Velocity Verlet
!> keeps each atom's next collision time with the atom (atoms%clock) so that a step touches only
!> the colliding atoms; energy stepping recomputes them after every list build (schedule).
!> The total momentum is not held: dof = d N (less d with zero_momentum).
module terrace_thermostat_andersen
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t, clock_unset
    use terrace_velocities, only: atom_mass
    use terrace_mpi_env, only: min_all
    use terrace_counter_rng, only: rng_block, rng_stream, rng_stream_t, unit_from_word, box_muller
    use terrace_thermostat, only: interval_thermostat_t, thermostat_params_t, thermostat_traits_t
    implicit none
    private

    ! streams of the counter-based generator (103, a per-step choice of earlier versions, is retired)
    integer, parameter :: stream_andersen_velocity = 104, stream_andersen_time = 105, stream_andersen_global = 106

    !> Energy stepping, global variant: every atom resampled at the multiples of interval (0: none,
    !> collisions atom by atom), the n_rescale-th keyed by n_rescale.
    type, extends(interval_thermostat_t), public :: andersen_t
        !> energy stepping, atom by atom: next collision time of each owned atom (same order as
        !> atoms), and the global first one
        real(dp), allocatable :: next_collision(:)
        integer(i8), allocatable :: collision_slot(:)
        integer, allocatable :: collision_index(:)
        real(dp) :: t_first = huge(1.0_dp)
    contains
        procedure :: setup => andersen_setup
        procedure, nopass :: style_traits => andersen_traits
        procedure :: post_kick => andersen_step
        procedure :: event_time => andersen_event_time
        procedure :: apply_event => andersen_apply_event
        procedure :: schedule => andersen_schedule
    end type andersen_t

    public :: andersen_next_collision

contains

    subroutine andersen_setup(self, p)
        class(andersen_t), intent(inout) :: self
        type(thermostat_params_t), intent(in) :: p
        call self%interval_thermostat_t%setup(p)
        self%t_first = huge(1.0_dp)
    end subroutine andersen_setup

    !> Its collisions are atom by atom at exact times: energy stepping and event-driven runs can
    !> take them.
    pure type(thermostat_traits_t) function andersen_traits() result(t)
        t = thermostat_traits_t(collides_atoms=.true., event_note='collisions at exact times')
    end function andersen_traits

    !> Maxwell-Boltzmann velocity at temperature temp for mass m (dimension 2: vz = 0), from one
    !> block keyed by (seed, stream, id, event, sub).
    function maxwell_velocity(self, id, event, sub, temp, m, stream) result(v)
        type(andersen_t), intent(in) :: self
        integer(i8), intent(in) :: id, event
        integer, intent(in) :: sub
        real(dp), intent(in) :: temp, m
        integer, intent(in) :: stream
        real(dp) :: v(3), u(4), z(4)
        u = unit_from_word(rng_block(self%seed, stream, id, event, sub))
        call box_muller(u(1), u(2), z(1), z(2))
        call box_muller(u(3), u(4), z(3), z(4))
        v = sqrt(self%boltz*temp/(m*self%mvv2e))*z(1:3)
        if (self%dimension == 2) v(3) = 0
    end function maxwell_velocity

    !> Velocity Verlet, after step n: atom i collides when its Poisson process of collision times
    !> has a point in ((n - 1) dt, n dt], which happens with probability 1 - exp(-dt/damping); it
    !> then gets a fresh Maxwell-Boltzmann velocity keyed by (seed, id, n). The first point after
    !> the last step looked at is kept in atoms%clock, which travels with the atom (reordering,
    !> migration): a step only compares each atom's clock with n dt and draws for the colliding
    !> atoms (about N dt/damping). A clock not set (the start of a run, a restart, atoms made
    !> afresh) is the first point after (n - 1) dt, the value the uninterrupted run holds there:
    !> nothing goes into a checkpoint, and a restart continues bitwise.
    subroutine andersen_step(self, atoms, dt, step, t_mid)
        class(andersen_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: dt, t_mid
        integer(i8), intent(in) :: step
        real(dp) :: temp, vnew(3), de, m, t_now, t_prev, t_next
        integer(i8) :: slot
        integer :: i, index
        call atoms%enable_clock()
        t_now = real(step, dp)*dt
        t_prev = real(step - 1, dp)*dt
        temp = self%target(step*dt)
        de = 0
        do i = 1, atoms%nlocal
            if (atoms%clock(i) > t_now) cycle
            if (atoms%clock(i) == clock_unset) then
                call andersen_next_collision(self%seed, self%damping, atoms%id(i), t_prev, atoms%clock(i), slot, index)
                if (atoms%clock(i) > t_now) cycle
            end if
            m = atom_mass(atoms, i)
            vnew = maxwell_velocity(self, atoms%id(i), step, 0, temp, m, stream_andersen_velocity)
            de = de + 0.5_dp*self%mvv2e*m*(sum(vnew**2) - sum(atoms%v(:, i)**2))
            atoms%v(:, i) = vnew
            call andersen_next_collision(self%seed, self%damping, atoms%id(i), t_now, t_next, slot, index)
            atoms%clock(i) = t_next
        end do
        self%ecouple_local = self%ecouple_local + de
    end subroutine andersen_step

    !> The first collision of atom `id` strictly after time t: its time, slot and index within the
    !> slot: a function of its arguments only, the same on every rank, before and after a restart.
    subroutine andersen_next_collision(seed, damping, id, t, t_next, slot, index)
        integer(i8), intent(in) :: seed, id
        real(dp), intent(in) :: damping, t
        real(dp), intent(out) :: t_next
        integer(i8), intent(out) :: slot
        integer, intent(out) :: index
        type(rng_stream_t) :: s
        real(dp) :: frac, start
        integer :: j
        slot = max(0_i8, int(floor(t/damping), i8))
        do
            s = rng_stream(seed, stream_andersen_time, id, slot)
            start = real(slot, dp)*damping
            frac = 0
            j = 0
            do
                frac = frac + s%exponential()
                if (frac >= 1) exit
                j = j + 1
                t_next = start + frac*damping
                if (t_next > t) then
                    index = j
                    return
                end if
            end do
            slot = slot + 1
        end do
    end subroutine andersen_next_collision

    !> Energy stepping: the next collision (atom by atom) or resampling (global variant).
    pure real(dp) function andersen_event_time(self) result(t)
        class(andersen_t), intent(in) :: self
        if (self%interval > 0) then
            t = real(self%n_rescale, dp)*self%interval
        else
            t = self%t_first
        end if
    end function andersen_event_time

    !> Energy stepping, atom by atom: the next collision time of every owned atom after time t
    !> (after a list build or a restart: the atoms were reordered or moved between ranks) and the
    !> global first one (collective). Nothing for the global variant.
    subroutine andersen_schedule(self, atoms, t)
        class(andersen_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: t
        integer :: i, n
        if (self%interval > 0) return
        n = atoms%nlocal
        if (allocated(self%next_collision)) then
            if (size(self%next_collision) < n) deallocate (self%next_collision, self%collision_slot, self%collision_index)
        end if
        if (.not. allocated(self%next_collision)) &
            allocate (self%next_collision(max(n, 16) + n/4), self%collision_slot(max(n, 16) + n/4), &
                      self%collision_index(max(n, 16) + n/4))
        do i = 1, n
            call andersen_next_collision(self%seed, self%damping, atoms%id(i), t, self%next_collision(i), &
                                         self%collision_slot(i), self%collision_index(i))
        end do
        self%t_first = huge(1.0_dp)
        if (n > 0) self%t_first = minval(self%next_collision(1:n))
        call min_all(self%t_first)
    end subroutine andersen_schedule

    !> Energy stepping at time t (collective). Atom by atom: every owned atom whose collision time
    !> is t gets a fresh Maxwell-Boltzmann velocity at the target temperature, keyed by (id, slot,
    !> index), and its next collision time. Global variant: every atom resampled, keyed by (id, the
    !> resampling's index). Then, with zero_momentum, the total momentum is removed.
    subroutine andersen_apply_event(self, atoms, t)
        class(andersen_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: t
        real(dp) :: vnew(3), m, temp
        integer :: i
        temp = self%target(t)
        if (self%interval > 0) then
            do i = 1, atoms%nlocal
                m = atom_mass(atoms, i)
                vnew = maxwell_velocity(self, atoms%id(i), self%n_rescale, 0, temp, m, stream_andersen_global)
                self%ecouple_local = self%ecouple_local + 0.5_dp*self%mvv2e*m*(sum(vnew**2) - sum(atoms%v(:, i)**2))
                atoms%v(:, i) = vnew
            end do
            self%n_rescale = self%n_rescale + 1
        else
            do i = 1, atoms%nlocal
                if (self%next_collision(i) > t) cycle
                m = atom_mass(atoms, i)
                vnew = maxwell_velocity(self, atoms%id(i), self%collision_slot(i), self%collision_index(i), temp, m, &
                                        stream_andersen_velocity)
                self%ecouple_local = self%ecouple_local + 0.5_dp*self%mvv2e*m*(sum(vnew**2) - sum(atoms%v(:, i)**2))
                atoms%v(:, i) = vnew
                call andersen_next_collision(self%seed, self%damping, atoms%id(i), t, self%next_collision(i), &
                                             self%collision_slot(i), self%collision_index(i))
            end do
            self%t_first = huge(1.0_dp)
            if (atoms%nlocal > 0) self%t_first = minval(self%next_collision(1:atoms%nlocal))
            call min_all(self%t_first)
        end if
        call self%hold_momentum(atoms)
    end subroutine andersen_apply_event

end module terrace_thermostat_andersen
