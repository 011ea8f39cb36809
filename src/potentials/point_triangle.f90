!> Euclidean distance from a point p to a triangle (a, b, c), its closest point and the distance's
!> first two derivatives along straight lines (the node-to-face contact, src/potentials/contact.f90).
!>
!> Closest point c = w1 a + w2 b + w3 c (barycentric weights w >= 0, sum 1) by the Voronoi regions
!> of the triangle: region 0 the face (all w > 0), 1..3 the edges opposite a, b, c (bc, ca, ab:
!> the opposite vertex's weight is 0), 4..6 the vertices a, b, c. d = |p - c|, n = (p - c)/d.
!> Derivatives of d with respect to the four points (envelope theorem: c minimises |p - y| over
!> the triangle, so moving c inside the triangle changes d only to second order):
!>   dd/dp = n,   dd/da = -w1 n,   dd/db = -w2 n,   dd/dc = -w3 n,
!> continuous across region boundaries wherever d > 0 (d is C1 there, C2 inside each region).
!>
!> Along the line p + s vp, a + s va, b + s vb, c + s vc (every point moves straight), with the
!> region fixed at the one of the current s (d'' jumps where the region changes, d' does not):
!>   d' = n . (vp - w1 va - w2 vb - w3 vc)                              (envelope theorem)
!> and d'' per region, all quantities at the current s, ' = d/ds:
!> - vertex (q = p - x, q' = vp - vx): d = |q|,  d' = q.q'/d,  d'' = (|q'|^2 - d'^2)/d.
!> - edge x -> y (e = y - x, q = p - x, e' = vy - vx, q' = vp - vx; the line through the edge):
!>   g = d^2 = A - B^2/C with A = q.q, B = q.e, C = e.e, A' = 2 q.q', A'' = 2 |q'|^2,
!>   B' = q'.e + q.e', B'' = 2 q'.e', C' = 2 e.e', C'' = 2 |e'|^2;
!>   g'  = A' - 2 B B'/C + B^2 C'/C^2,
!>   g'' = A'' - 2 (B'^2 + B B'')/C + 4 B B' C'/C^2 + B^2 C''/C^2 - 2 B^2 C'^2/C^3,
!>   d' = g'/(2d),  d'' = (g'' - 2 d'^2)/(2d).
!> - face (the plane turns with its vertices): N = (b - a) x (c - a), q = p - a,
!>   N' = (vb - va) x (c - a) + (b - a) x (vc - va), N'' = 2 (vb - va) x (vc - va), q'' = 0;
!>   u = N.q, u' = N'.q + N.q', u'' = N''.q + 2 N'.q'; M = N.N, M' = 2 N.N', M'' = 2 (N'.N' + N.N'');
!>   d = sigma u M^-1/2 (sigma = sign u),
!>   d'  = sigma (u' M^-1/2 - u M' M^-3/2 / 2),
!>   d'' = sigma (u'' M^-1/2 - u' M' M^-3/2 - u M'' M^-3/2 / 2 + 3/4 u M'^2 M^-5/2).
!> The formulas are exact for the distance to the vertex, the edge's line or the face's plane, which
!> equals d while the region holds.
module terrace_point_triangle
    use terrace_kinds, only: dp
    use terrace_vec3, only: cross
    implicit none
    private

    integer, parameter, public :: region_face = 0                !< 1..3 edges, 4..6 vertices

    public :: closest_point, distance_derivatives

contains

    !> The closest point of triangle (a, b, c) to p: weights w (c = w1 a + w2 b + w3 c) and region
    !> (0 face, 1 edge bc, 2 edge ca, 3 edge ab, 4 vertex a, 5 vertex b, 6 vertex c).
    pure subroutine closest_point(p, a, b, c, w, region)
        real(dp), intent(in) :: p(3), a(3), b(3), c(3)
        real(dp), intent(out) :: w(3)
        integer, intent(out) :: region
        real(dp) :: ab(3), ac(3), ap(3), bp(3), cp(3), d1, d2, d3, d4, d5, d6, va, vb, vc, t, den
        ab = b - a; ac = c - a; ap = p - a
        d1 = dot_product(ab, ap); d2 = dot_product(ac, ap)
        if (d1 <= 0 .and. d2 <= 0) then
            w = [1, 0, 0]; region = 4; return
        end if
        bp = p - b
        d3 = dot_product(ab, bp); d4 = dot_product(ac, bp)
        if (d3 >= 0 .and. d4 <= d3) then
            w = [0, 1, 0]; region = 5; return
        end if
        vc = d1*d4 - d3*d2
        if (vc <= 0 .and. d1 >= 0 .and. d3 <= 0) then
            t = d1/(d1 - d3)
            w = [1 - t, t, 0.0_dp]; region = 3; return
        end if
        cp = p - c
        d5 = dot_product(ab, cp); d6 = dot_product(ac, cp)
        if (d6 >= 0 .and. d5 <= d6) then
            w = [0, 0, 1]; region = 6; return
        end if
        vb = d5*d2 - d1*d6
        if (vb <= 0 .and. d2 >= 0 .and. d6 <= 0) then
            t = d2/(d2 - d6)
            w = [1 - t, 0.0_dp, t]; region = 2; return
        end if
        va = d3*d6 - d5*d4
        if (va <= 0 .and. (d4 - d3) >= 0 .and. (d5 - d6) >= 0) then
            t = (d4 - d3)/((d4 - d3) + (d5 - d6))
            w = [0.0_dp, 1 - t, t]; region = 1; return
        end if
        den = 1/(va + vb + vc)
        w(2) = vb*den; w(3) = vc*den; w(1) = 1 - w(2) - w(3)
        region = region_face
    end subroutine closest_point

    !> d, d' and d'' along the straight motion (x: p, a, b, c as columns; v their velocities) with
    !> the closest point's region fixed (see the module header), region from closest_point at x.
    !> d = 0 (the point on the triangle): d' = d'' = 0.
    pure subroutine distance_derivatives(x, v, region, d, d1, d2)
        real(dp), intent(in) :: x(3, 4), v(3, 4)
        integer, intent(in) :: region
        real(dp), intent(out) :: d, d1, d2
        real(dp) :: q(3), qv(3), e(3), ev(3), aa, a1, a2, b, b1, b2, cc, c1, c2, g1, g2
        real(dp) :: nn(3), n1(3), n2(3), u, u1, u2, m, mm1, mm2, sg, rm
        integer :: i, j
        d = 0; d1 = 0; d2 = 0
        select case (region)
        case (4:6)
            i = region - 2
            q = x(:, 1) - x(:, i); qv = v(:, 1) - v(:, i)
            d = norm2(q)
            if (.not. (d > 0)) return
            d1 = dot_product(q, qv)/d
            d2 = (dot_product(qv, qv) - d1*d1)/d
        case (1:3)
            ! edge opposite vertex region: from vertex i to vertex j (columns 2..4)
            i = 2 + mod(region, 3); j = 2 + mod(region + 1, 3)
            q = x(:, 1) - x(:, i); qv = v(:, 1) - v(:, i)
            e = x(:, j) - x(:, i); ev = v(:, j) - v(:, i)
            aa = dot_product(q, q); a1 = 2*dot_product(q, qv); a2 = 2*dot_product(qv, qv)
            b = dot_product(q, e); b1 = dot_product(qv, e) + dot_product(q, ev); b2 = 2*dot_product(qv, ev)
            cc = dot_product(e, e); c1 = 2*dot_product(e, ev); c2 = 2*dot_product(ev, ev)
            d = sqrt(max(aa - b*b/cc, 0.0_dp))
            if (.not. (d > 0)) return
            g1 = a1 - 2*b*b1/cc + b*b*c1/cc**2
            g2 = a2 - 2*(b1*b1 + b*b2)/cc + 4*b*b1*c1/cc**2 + b*b*c2/cc**2 - 2*b*b*c1*c1/cc**3
            d1 = g1/(2*d)
            d2 = (g2 - 2*d1*d1)/(2*d)
        case default
            q = x(:, 1) - x(:, 2); qv = v(:, 1) - v(:, 2)
            nn = cross(x(:, 3) - x(:, 2), x(:, 4) - x(:, 2))
            n1 = cross(v(:, 3) - v(:, 2), x(:, 4) - x(:, 2)) + cross(x(:, 3) - x(:, 2), v(:, 4) - v(:, 2))
            n2 = 2*cross(v(:, 3) - v(:, 2), v(:, 4) - v(:, 2))
            u = dot_product(nn, q); u1 = dot_product(n1, q) + dot_product(nn, qv)
            u2 = dot_product(n2, q) + 2*dot_product(n1, qv)
            m = dot_product(nn, nn); mm1 = 2*dot_product(nn, n1); mm2 = 2*(dot_product(n1, n1) + dot_product(nn, n2))
            if (.not. (m > 0)) return
            sg = sign(1.0_dp, u)
            rm = 1/sqrt(m)
            d = sg*u*rm
            if (.not. (d > 0)) then
                d = 0; return
            end if
            d1 = sg*(u1*rm - 0.5_dp*u*mm1*rm**3)
            d2 = sg*(u2*rm - u1*mm1*rm**3 - 0.5_dp*u*mm2*rm**3 + 0.75_dp*u*mm1*mm1*rm**5)
        end select
    end subroutine distance_derivatives

end module terrace_point_triangle
