"""Other edges beside a component's outline (core.other_edges), on a drawn image: a dark
disc (the component) and a bone-like darker band whose straight edge touches the disc."""
import cv2
import numpy as np

from fluorogui.core.other_edges import NEAR_PX, near_other_edges

CENTRE, RADIUS = np.array([100.0, 100.0]), 40.0


def _outline(n=400):
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return CENTRE + RADIUS * np.column_stack([np.cos(angle), np.sin(angle)]), angle


def _image(bone=True, seed=0):
    """Air 1000, the disc 50, a band of bone (800) right of u = 140, where it touches the
    disc; blurred (sigma 1 px) and with a little noise."""
    image = np.full((200, 200), 1000.0)
    if bone:
        image[:, 141:] = 800.0  # the band's edge between pixels 140 and 141
    disc = np.zeros(image.shape, np.uint8)
    cv2.circle(disc, (1600, 1600), int(RADIUS * 16), 1, -1, shift=4)
    image[disc > 0] = 50.0
    image = cv2.GaussianBlur(image, (0, 0), 1.0)
    return image + np.random.default_rng(seed).normal(0, 5.0, image.shape)


def test_points_beside_a_bone_edge_are_found_also_where_it_touches_the_outline():
    outline, angle = _outline()
    near = near_other_edges(_image(), outline)
    gap = np.abs(140.5 - outline[:, 0])  # distance to the band's edge
    assert near[gap < NEAR_PX - 1.5].all()  # the touching stretch too: the edge extended along itself
    assert not near[gap > NEAR_PX + 1.5].any()
    # about the 68 deg of the disc within 7 px of the line, nothing on the far side
    assert 0.15 < near.mean() < 0.25, near.mean()
    assert not near[np.cos(angle) < 0].any()


def test_a_component_alone_has_no_other_edges():
    outline, _ = _outline()
    assert not near_other_edges(_image(bone=False), outline).any()


def test_edges_under_the_exclusion_mask_do_not_count():
    outline, _ = _outline()
    exclude = np.zeros((200, 200), bool)
    exclude[:, 138:] = True  # e.g. another component there
    assert not near_other_edges(_image(), outline, exclude).any()
